"""Illumination techniques shipped with vtkvol (``vtkvol.plugins``).

One module per technique, each paired with ``resources/shaders/<name>.glsl`` and registered under
the ``vtkvol.techniques`` entry point. See ``vtkvol.engine.technique`` for the shape they share.
"""
