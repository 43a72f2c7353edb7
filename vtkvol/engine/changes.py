"""Change tracking: what a technique must catch up on at its next ``prepare``.

A service of :class:`~vtkvol.engine.illuminator.Illuminator`. Edits made through the host's
setters are recorded as they happen (:attr:`ChangeTracker.pending`); what user code changed
on the VTK objects directly is found at a frame's start by comparing cheap signatures: the
opacity source's (data, transfer functions, crop, clipping, weights, placement), the lights'
in dataset space and, for view-dependent techniques, the camera's. Camera moves therefore
never make a technique recompute unless it depends on the view.
"""

from __future__ import annotations

from typing import Any

from vtkvol.engine.technique import Changes


def first_changes() -> Changes:
    """The changes of a technique's first frame: everything."""
    return Changes(first=True, opacity=True, lights=True)


class ChangeTracker:
    """The pending :class:`Changes` of one host and the signatures they are detected from."""

    def __init__(self, host: Any) -> None:
        # The host (engine/illuminator.py), typed loosely: importing it would close an
        # import circle (scripts/import_graph.py).
        self._host = host
        #: What changed since the technique last prepared (merged over skipped frames).
        self.pending = first_changes()
        #: The opacity source's signature when the changes were last detected.
        self.opacity_signature: tuple | None = None
        self._view_signature: tuple | None = None

    def restart(self) -> None:
        """A new technique: it sees everything as changed."""
        self.pending = first_changes()

    def take(self) -> Changes:
        """The pending changes, which are then cleared (the technique prepares for them)."""
        changes, self.pending = self.pending, Changes()
        return changes

    def keep(self, changes: Changes) -> None:
        """Put taken ``changes`` back (a deferred prepare), merged with what came since."""
        self.pending = changes.merge(self.pending)

    def detect(self) -> None:
        """Compare the signatures with the last frame's and record what differs."""
        host = self._host
        signature = host.opacity.signature()
        if signature != self.opacity_signature:
            self.opacity_signature = signature
            self.pending.opacity = True
        geometry, colours = host.light_rig.changed(host.light_specs())
        self.pending.lights |= geometry
        self.pending.light_colors |= colours
        if host.spec.has("view_dependent"):
            view = self._camera_signature()
            if view != self._view_signature:
                self._view_signature = view
                self.pending.view = True

    def _camera_signature(self) -> tuple:
        renderer = self._host.renderer
        cam = renderer.GetActiveCamera()
        return (
            tuple(cam.GetPosition()), tuple(cam.GetFocalPoint()), tuple(cam.GetViewUp()),
            cam.GetViewAngle(), cam.GetParallelProjection(), cam.GetParallelScale(),
            tuple(renderer.GetSize()),
        )

    @staticmethod
    def needs_prepare(changes: Changes) -> bool:
        """Whether ``changes`` may make a (non-progressive) technique recompute."""
        return bool(changes.first or changes.opacity or changes.lights or changes.parameters
                    or changes.view or changes.invalidates)

    def has_pending(self) -> bool:
        """Whether changes wait for a prepare (deferred ones included) that may recompute,
        counting an opacity change not yet detected."""
        return self.needs_prepare(self.pending) or (
            self.opacity_signature is not None
            and self._host.opacity.signature() != self.opacity_signature)
