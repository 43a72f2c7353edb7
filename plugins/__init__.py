"""Illumination techniques shipped with vtkvol (``vtkvol.plugins``).

One package per technique: ``__init__`` holds its VTK-free declaration (``TECHNIQUE``, a
:class:`vtkvol.model.techniques.TechniqueSpec`), ``technique.py`` its engine part and
``shaders/`` its GLSL. Each is registered under the ``vtkvol.techniques`` entry point.
"""
