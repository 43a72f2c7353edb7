"""``VolumeScene``: a :class:`SceneModel` and a :class:`VolumeData` made into a VTK scene.

The scene listens to the model and applies each change to the VTK objects it concerns, one
handler per property (napari's ``_on_<x>_change``): a TF edit on channel 1 rebuilds channel 1's
functions only, and background, jitter, channel names, camera or light colours never make the
illumination recompute. It writes the model in two places only:
:meth:`VolumeScene.sync_camera_to_model` (the camera is moved by the interactor) and
``illumination.method`` when the technique failed and the host fell back to local shading.
Illumination is delegated to an :class:`~vtkvol.engine.illuminator.Illuminator`, the same host
that :func:`vtkvol.illuminate` attaches to foreign volumes.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Literal

import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk

from vtkvol.engine.exposure import ExposureMeasurement, measure_auto_exposure
from vtkvol.engine.framing import visible_bounds
from vtkvol.engine.illuminator import Illuminator
from vtkvol.engine.overlays import SceneOverlays
from vtkvol.engine.shaders import ReplacementSet
from vtkvol.engine.slices import shown_tf, snap_cursor
from vtkvol.engine.tf2d import (
    TABLE_SHAPE,
    TableImage,
    gradient_axis_max,
    multi_component_fixes,
)
from vtkvol.model.defaults import default_channels
from vtkvol.model.evented import Signal, element_fields, fields_of, subfields, touches
from vtkvol.model.scene import Channel, SceneModel
from vtkvol.model.techniques import get_spec
from vtkvol.model.transfer_function import table_from_1d

if TYPE_CHECKING:
    from vtkvol.io import VolumeData

#: Model blend mode → vtkVolumeMapper blend mode.
_BLEND = {
    "composite": vtk.vtkVolumeMapper.COMPOSITE_BLEND,
    "mip": vtk.vtkVolumeMapper.MAXIMUM_INTENSITY_BLEND,
    "minip": vtk.vtkVolumeMapper.MINIMUM_INTENSITY_BLEND,
    "average": vtk.vtkVolumeMapper.AVERAGE_INTENSITY_BLEND,
    "additive": vtk.vtkVolumeMapper.ADDITIVE_BLEND,
    "isosurface": vtk.vtkVolumeMapper.ISOSURFACE_BLEND,
}
#: Fields that are editor state only (the TF editor's displayed-value window): no VTK change.
#: What the automatic exposure depends on (the model's parts; ``render`` apart from the fields
#: in _RENDER_NOT_EXPOSURE). Not the camera: the exposure holds while the view turns.
_EXPOSURE_INPUTS = ("channels", "lights", "illumination", "crop", "slice_weights", "clip_plane")
_RENDER_NOT_EXPOSURE = frozenset({"exposure", "background", "interactive_sample_distance",
                                  "interactive_image_factor", "jitter"})
_EDITOR_ONLY = (("channels", "tf", "window"), ("channels", "tf", "window_range"),
                ("channels", "tf2d", "gradient_max"))
#: Per-channel fields that change nothing VTK shows (the channel list's name and tint).
_LABEL_ONLY = ("name", "color")
#: Weight-table resolution for the slice-contribution functions.
WEIGHT_SAMPLES = 256

# VTK mixes independent components with an opacity-weighted mean alpha ("additive" colours).
# "composite" mixing treats the channels as independent absorbers: alpha = 1 - prod(1 - a_i).
_VTK_MIX_LINE = "tmp.w += ((color[i].w * color[i].w)/totalAlpha);"
_ABSORBER_MIX_LINE = "tmp.w = 1.0 - (1.0 - tmp.w) * (1.0 - color[i].w * in_componentWeight[i]);"


class VolumeScene:
    """Owns the ``vtkVolume`` for one :class:`SceneModel` in a ``vtkRenderer``.

    Parameters
    ----------
    renderer
        Where to add the volume.
    model
        The state to show; changes to it are applied as they happen.
    data
        The voxels. ``None`` shows nothing until :meth:`set_data`.
    request_render
        Called when the view needs a new frame (the app coalesces these on a Qt timer);
        default: render the window at once.
    framing
        What :meth:`reset_camera` frames: ``"box"``, the data's whole box, or ``"visible"``,
        the voxels the transfer functions make visible (the app's first view and "reset view":
        a mostly transparent stack then fills the view with its object).
    """

    def __init__(
        self,
        renderer: vtk.vtkRenderer,
        model: SceneModel,
        data: VolumeData | None = None,
        *,
        request_render: Callable[[], None] | None = None,
        framing: Literal["box", "visible"] = "box",
    ) -> None:
        self.renderer = renderer
        self.framing = framing
        self.model = model
        self._request_render = request_render
        self.data: VolumeData | None = None
        self._image: vtk.vtkImageData | None = None
        self._keepalive: np.ndarray | None = None  # numpy buffer VTK reads without copying
        self._interactive = False
        self._syncing_camera = False
        self.illuminator: Illuminator | None = None
        #: The automatic exposure's last factor (1 = none), and its measurement.
        self.auto_exposure_factor = 1.0
        self.exposure_measurement: ExposureMeasurement | None = None
        self._exposure_stale = True
        #: Emits one user-facing message when the illumination technique failed (the model's
        #: method has then been set back to what is shown).
        self.error = Signal()
        #: Emits (iteration, converged) while a progressive technique refines.
        self.progress = Signal()
        #: Wraps the engine's own write of ``illumination.method`` after a failure. The app
        #: sets its undo recorder's ``amending`` here, so that the fallback is not an edit of
        #: its own (undoing the user's choice then returns to what was shown before it).
        self.engine_edit: Callable[[], contextlib.AbstractContextManager[None]] = (
            contextlib.nullcontext)
        self._color_functions: list[vtk.vtkColorTransferFunction] = []
        self._opacity_functions: list[vtk.vtkPiecewiseFunction] = []
        #: One 2-D table per channel while any channel uses a 2-D TF (VTK's TF mode is per
        #: property, so then every channel is classified through a table; 1-D channels
        #: through their TF made constant along the gradient axis).
        self._tables: list[TableImage] = []
        self.volume = vtk.vtkVolume()
        self.mapper = vtk.vtkOpenGLGPUVolumeRayCastMapper()
        self.mapper.SetAutoAdjustSampleDistances(0)  # quality never changes behind the user's back
        self.mapper.SetLockSampleDistanceToInputSpacing(0)
        self.property = vtk.vtkVolumeProperty()
        self.property.SetInterpolationTypeToLinear()
        self.volume.SetMapper(self.mapper)
        self.volume.SetProperty(self.property)
        self._tf2d_fixes = ReplacementSet(self.volume.GetShaderProperty())
        #: Scale bar, orientation axes, bounding box and colour legend (``model.overlays``).
        self.overlays = SceneOverlays(renderer)
        model.changed.connect(self._on_model_changed)
        if data is not None:
            self.set_data(data)

    # -- data -------------------------------------------------------------------------------------
    def set_data(self, data: VolumeData, *, reset_channels: bool | None = None) -> None:
        """Show ``data``. Channels are reset to defaults when their count differs from the
        model's (or when ``reset_channels``); otherwise the model's channels are kept."""
        self.data = data
        self._image, self._keepalive = _to_image(data)
        self.mapper.SetInputData(self._image)
        self._exposure_stale = True
        count_changed = len(self.model.channels) != data.n_channels
        if reset_channels or (reset_channels is None and count_changed):
            with self.model.batch():
                self.model.channels = default_channels(data)
        if self.renderer.HasViewProp(self.volume) == 0:
            self.renderer.AddVolume(self.volume)
        if self.illuminator is None:
            self.illuminator = Illuminator(
                self.volume,
                self.renderer,
                method=self.model.illumination.method,
                lights=self.model.lights,
                parameters=self.model.illumination.values_for(),
            )
            self.illuminator.on_error = self._on_illumination_error
            self.illuminator.on_progress = self._on_illumination_progress
        self.overlays.set_bounds(self.bounds)
        self._apply_all()
        if self.model.camera.position is None:
            self.reset_camera()
        self.request_render()

    def set_voxels(self, data: VolumeData) -> None:
        """Show other voxels of the same geometry (another time point of the series): only
        the image changes. Transfer functions, channels, camera, crop, slice weights, clipping
        plane, lights and method stay as they are; the illumination recomputes at the next
        frame (its signature includes the input image).

        Raises ``ValueError`` when ``data`` differs from the shown data in shape, channel
        count or voxel size (x, y, z µm), and ``RuntimeError`` before any :meth:`set_data`.
        """
        if self.data is None:
            raise RuntimeError("set_voxels needs data shown first (set_data)")
        old = self.data
        if (data.array.shape != old.array.shape
                or tuple(data.voxel_size_um) != tuple(old.voxel_size_um)):
            z, y, x = old.shape_zyx
            nz, ny, nx = data.shape_zyx
            raise ValueError(
                f"the new voxels ({data.n_channels} channel(s) of {nx}×{ny}×{nz}) do not match "
                f"the shown volume ({old.n_channels} channel(s) of {x}×{y}×{z}, the same voxel "
                "size); use set_data for other data")
        self.data = data
        self._image, self._keepalive = _to_image(data)
        self.mapper.SetInputData(self._image)
        self.request_render()

    @property
    def bounds(self) -> tuple[float, float, float, float, float, float]:
        """(xmin, xmax, ymin, ymax, zmin, zmax) of the data in world µm (voxel centres)."""
        if self._image is None:
            return (0.0, 1.0, 0.0, 1.0, 0.0, 1.0)
        return tuple(self._image.GetBounds())  # type: ignore[return-value]

    # -- model → VTK ----------------------------------------------------------------------------
    def _on_model_changed(self, paths: frozenset[str]) -> None:
        if self.data is None:
            return
        paths = frozenset(p for p in paths if tuple(fields_of(p)[:3]) not in _EDITOR_ONLY
                          and tuple(fields_of(p)[:2]) != ("volume", "time_index"))
        if not paths:
            return  # (the time index: the new voxels come with set_voxels, and their frame)
        if touches(paths, "cursor"):
            self._apply_cursor()
            if paths == {"cursor"} and not self.model.overlays.slice_planes:
                return  # only the slice views show it: no frame
        if touches(paths, "channels"):
            self._on_channels_change(paths)
        if touches(paths, "render"):
            self._on_render_change(subfields(paths, "render"))
        if touches(paths, "lights"):
            self.illuminator.set_lights(self.model.lights)  # type: ignore[union-attr]
        if touches(paths, "illumination"):
            self._apply_illumination()
        if touches(paths, "lights") or touches(paths, "illumination"):
            self._apply_renderer()  # what a renderer supports depends on both
        if touches(paths, "crop"):
            self._apply_crop()
        if touches(paths, "slice_weights"):
            self._apply_slice_weights()
        if touches(paths, "clip_plane"):
            self._apply_clip_plane()
        if touches(paths, "camera") and not self._syncing_camera:
            self._apply_camera()
        if any(touches(paths, part) for part in _EXPOSURE_INPUTS) or (
                touches(paths, "render")
                and (subfields(paths, "render") or {""}) - _RENDER_NOT_EXPOSURE):
            self._exposure_stale = True
        if touches(paths, "overlays"):
            self._apply_legend()  # its channel list is kept up to date only while shown
            self.overlays.apply(self.model.overlays)
        if touches(paths, "channels") and self.model.overlays.color_legend:
            self._apply_legend()
        self.request_render()

    def _on_channels_change(self, paths: frozenset[str]) -> None:
        changed = element_fields(paths, "channels")
        if (changed is None or any("tf_linked_to" in names for names in changed.values())
                or len(self._opacity_functions) != len(self.model.channels)):
            # A new channel list or a new link: which function follows which has changed.
            self._apply_channels()
            return
        if any("tf_mode" in names for names in changed.values()):
            self._apply_tf_mode()  # the property's mode may flip: every table is rebuilt
        for c, names in changed.items():
            if names <= set(_LABEL_ONLY):
                continue
            # Gamma and the labels display change what the TF is drawn as.
            if names & {"tf", "tf2d", "gamma", "labels"} or "" in names:
                # A channel linked to this one follows it.
                for target, channel in enumerate(self.model.channels):
                    if target == c or channel.tf_linked_to == c:
                        self._apply_channel_tf(target)
                        self._apply_channel_table(target)
                if c == 0 and self.model.render.blend_mode == "isosurface":
                    self._apply_shading_constants()  # the default isovalue follows channel 0
            if "visible" in names or "" in names:
                self._apply_channel_visibility(c)

    def _on_render_change(self, names: set[str] | None) -> None:
        """Apply the render settings ``names`` changed (None: all of them)."""
        every = names is None
        names = names or set()
        render = self.model.render
        if every or "background" in names:
            self.renderer.SetBackground(*render.background)
            self.overlays.set_background(render.background)
        if every or "jitter" in names:
            self.mapper.SetUseJittering(int(render.jitter))
        if every or names & {"sample_distance", "interactive_sample_distance",
                             "interactive_image_factor"}:
            self._apply_sampling()
        if every or names & {"blend_mode", "channel_mixing"}:
            self._apply_blending()
        if every or names & {"opacity_unit_distance", "shade", "ambient", "diffuse", "specular",
                             "specular_power", "blend_mode", "isosurface_value"}:
            self._apply_shading_constants()
        if every or names & {"albedo", "phase_g"}:
            self._apply_material()
        if every or names & {"exposure", "auto_exposure", "fill"}:
            self._apply_exposure()
        if every or "interpolation" in names:
            nearest = render.interpolation == "nearest"
            self.property.SetInterpolationType(
                vtk.VTK_NEAREST_INTERPOLATION if nearest else vtk.VTK_LINEAR_INTERPOLATION)
            if self.illuminator is not None:
                # Nearest is VTK's own texture filter; the host's shader path stays trilinear.
                self.illuminator.set_interpolation(
                    "trilinear" if nearest else render.interpolation)
        if (every or "empty_space_skipping" in names) and self.illuminator is not None:
            self.illuminator.set_empty_space_skipping(render.empty_space_skipping)
        if (every or "multichannel_lighting" in names) and self.illuminator is not None:
            self.illuminator.set_multichannel_lighting(render.multichannel_lighting)
        if (every or "preintegration" in names) and self.illuminator is not None:
            self.illuminator.set_preintegration(render.preintegration)
        if (every or "adaptive_sampling" in names) and self.illuminator is not None:
            self.illuminator.set_adaptive_sampling(render.adaptive_sampling)
        if every or names & {"renderer", "blend_mode"}:
            self._apply_renderer()

    def _apply_renderer(self) -> None:
        """Draw with ``render.renderer`` where the combination is supported, else with VTK's
        ray caster and the reason on :attr:`error` (vtkvol.engine.renderers)."""
        if self.illuminator is not None:
            from vtkvol.engine.renderers import apply_renderer

            apply_renderer(self.illuminator, self.model.render.renderer, self.error.emit)

    def _apply_all(self) -> None:
        self._on_render_change(None)
        self._apply_channels()
        self._apply_illumination()
        self._apply_crop()
        self._apply_slice_weights()
        self._apply_clip_plane()
        if self.model.camera.position is not None:
            self._apply_camera()
        assert self.illuminator is not None
        self.illuminator.set_lights(self.model.lights)
        self._apply_legend()
        self._apply_cursor()
        self.overlays.apply(self.model.overlays)

    def _apply_cursor(self) -> None:
        """The slice planes' outlines pass through the cursor (snapped to a voxel centre and
        clamped into the data, as the slice views show it)."""
        if self.data is not None:
            self.overlays.set_cursor(snap_cursor(self.model.cursor, self.data.array.shape,
                                                 tuple(self.data.voxel_size_um)))

    def _apply_legend(self) -> None:
        """The colour legend shows each visible channel's colour function."""
        self.overlays.set_legend_channels([
            (channel.name, self._color_functions[c])
            for c, channel in enumerate(self.model.channels)
            if channel.visible and c < len(self._color_functions)
        ])

    def _apply_channels(self) -> None:
        """(Re)build every channel: one colour and one opacity function per channel, kept and
        edited in place afterwards so that other channels' functions keep their MTime."""
        prop = self.property
        n = len(self.model.channels)
        prop.SetIndependentComponents(True)  # one TF per channel, also for a single channel
        self._color_functions = [vtk.vtkColorTransferFunction() for _ in range(n)]
        self._opacity_functions = [vtk.vtkPiecewiseFunction() for _ in range(n)]
        for c in range(n):
            prop.SetColor(c, self._color_functions[c])
            prop.SetScalarOpacity(c, self._opacity_functions[c])
            self._apply_channel_tf(c)
            self._apply_channel_visibility(c)
        self._apply_shading_constants()
        self._apply_tf_mode()

    # -- 2-D transfer functions (docs/transfer-functions-2d.md) ---------------------------------
    @property
    def uses_2d_tf(self) -> bool:
        """True when some channel is classified by its 2-D TF (VTK's property is then in
        2-D mode for every channel)."""
        return any(self._effective_channel(ch).tf_mode == "2d" for ch in self.model.channels)

    def tf2d_axes(self, c: int) -> tuple[tuple[float, float], tuple[float, float]]:
        """(value range in data units, gradient range in data units per µm) of channel
        ``c``'s 2-D table: VTK's axes for this data (the editor shows the same)."""
        value_range = self._value_range(c)
        spacing = self.data.voxel_size_um if self.data is not None else (1.0, 1.0, 1.0)
        return value_range, (0.0, gradient_axis_max(value_range, tuple(spacing)))

    def _value_range(self, c: int) -> tuple[float, float]:
        if self._image is None:
            return (0.0, 1.0)
        lo, hi = self._image.GetPointData().GetScalars().GetRange(c)
        return (float(lo), float(hi))

    def _apply_tf_mode(self) -> None:
        """Switch VTK between 1-D and 2-D classification and (re)build every table."""
        prop = self.property
        n = len(self.model.channels)
        if not self.uses_2d_tf or self._image is None:
            if prop.GetTransferFunctionMode() != vtk.vtkVolumeProperty.TF_1D:
                prop.SetTransferFunctionModeTo1D()
            self._tables = []
            self._tf2d_fixes.clear()
            return
        if len(self._tables) != n:
            self._tables = [TableImage() for _ in range(n)]
        for c in range(n):
            self._apply_channel_table(c)
            prop.SetTransferFunction2D(c, self._tables[c].image)
        prop.SetTransferFunctionModeTo2D()
        fixes = multi_component_fixes(n) if n > 1 else {}
        self._tf2d_fixes.install({(tag, "pre"): code for tag, code in fixes.items()})

    def _apply_channel_table(self, c: int) -> None:
        """Rasterise channel ``c``'s classification into its table (2-D mode only)."""
        if not self._tables or c >= len(self._tables):
            return
        channel = self.model.channels[c]
        effective = self._effective_channel(channel)
        value_range, gradient_range = self.tf2d_axes(c)
        if value_range[1] <= value_range[0]:
            value_range = (value_range[0], value_range[0] + 1.0)
        if len(self.model.channels) == 1 and not channel.visible:
            rgba = np.zeros((*TABLE_SHAPE, 4), np.float32)  # a single channel: hide it here
        elif effective.tf_mode == "2d":
            rgba = effective.tf2d.table(value_range, gradient_range, TABLE_SHAPE)
        else:
            rgba = table_from_1d(self._effective_tf(channel), value_range, TABLE_SHAPE)
        step, unit = self._table_step(c)
        self._tables[c].set_table(rgba, step, unit)

    def _table_step(self, c: int) -> tuple[float, float]:
        """(ray step, opacity unit distance) in µm that the table's alpha is made for."""
        return (float(self.mapper.GetSampleDistance()),
                float(self.property.GetScalarOpacityUnitDistance(c)))

    def _apply_table_steps(self) -> None:
        for c, table in enumerate(self._tables):
            table.set_step(*self._table_step(c))

    def _effective_channel(self, channel: Channel) -> Channel:
        """The channel whose transfer functions ``channel`` shows (itself or its link)."""
        link = channel.tf_linked_to
        channels = self.model.channels
        if link is not None and 0 <= link < len(channels) and channels[link] is not channel:
            return channels[link]
        return channel

    def _apply_channel_tf(self, c: int) -> None:
        channel = self.model.channels[c]
        tf = self._effective_tf(channel)
        if channel.labels is None:
            tf = tf.reduced() or tf  # at most MAX_POINTS each: bounded time for any function
        # (A label channel's steps must stay exact: resampled, the colours of more than 511
        # ids blend. Its points are bounded anyway: 2 per id, at most MAX_ID_SPAN ids.)
        ctf, otf = self._color_functions[c], self._opacity_functions[c]
        # Bulk fills: AddPoint re-sorts the whole function per point (a TF of 100 000 points
        # took minutes); the points are sorted already.
        ctf.RemoveAllPoints()
        ctf.FillFromDataPointer(len(tf.colors), np.asarray(tf.colors, np.float64).ravel())
        otf.RemoveAllPoints()
        if len(self.model.channels) == 1 and not channel.visible:
            otf.AddPoint(-1e30, 0.0)  # a single channel cannot be weighted away: hide it here
            otf.AddPoint(1e30, 0.0)
        else:
            otf.FillFromDataPointer(len(tf.opacity), np.asarray(tf.opacity, np.float64).ravel())

    def _apply_channel_visibility(self, c: int) -> None:
        channel = self.model.channels[c]
        if len(self.model.channels) == 1:
            self._apply_channel_tf(c)
            self._apply_channel_table(c)
        else:
            self.property.SetComponentWeight(c, 1.0 if channel.visible else 0.0)

    def _apply_shading_constants(self) -> None:
        """Per-component unit distance and shading constants, and the isosurface value."""
        prop, render = self.property, self.model.render
        unit = render.opacity_unit_distance or self._min_spacing()
        for c in range(len(self.model.channels)):
            if prop.GetScalarOpacityUnitDistance(c) != unit:
                prop.SetScalarOpacityUnitDistance(c, unit)
            prop.SetShade(c, int(render.shade))
            prop.SetAmbient(c, render.ambient)
            prop.SetDiffuse(c, render.diffuse)
            prop.SetSpecular(c, render.specular)
            prop.SetSpecularPower(c, render.specular_power)
        self._apply_table_steps()
        if render.blend_mode == "isosurface":
            iso = prop.GetIsoSurfaceValues()
            iso.SetNumberOfContours(1)
            iso.SetValue(0, self._isosurface_value())

    def _apply_material(self) -> None:
        if self.illuminator is not None:
            render = self.model.render
            self.illuminator.set_material(albedo=render.albedo, phase_g=render.phase_g)

    def _apply_exposure(self) -> None:
        if self.illuminator is not None:
            render = self.model.render
            factor = self.auto_exposure_factor if render.auto_exposure else 1.0
            self.illuminator.set_exposure(render.exposure * factor, render.fill)

    def update_exposure(self) -> bool:
        """Measure the automatic exposure (:mod:`vtkvol.engine.exposure`) if anything it
        depends on changed since the last measurement (not the camera: the exposure does not
        flicker while the view turns). Renders two coarse frames that are not shown; call it
        before a full-quality frame, with the window's context usable. Returns whether the
        factor changed (the next frame then looks different)."""
        render = self.model.render
        if (not render.auto_exposure or not self._exposure_stale or self.illuminator is None
                or self._image is None or self.renderer.GetRenderWindow() is None):
            return False
        self._exposure_stale = False
        method = self.model.illumination.method
        if (method == "local" or not render.shade or render.blend_mode != "composite"
                or get_spec(method).lighting != "surface" or get_spec(method).has("adds_light")
                or render.renderer != "raycast"):
            # Nothing takes light away (local shading's own brightness; unshaded or a MIP is
            # not lit), or a medium technique: its light is its physics (scattering returns
            # what attenuation takes; measured 0.89–0.99 of local shading's mean brightness,
            # docs/architecture.md), and its unobstructed medium is no local-shading reference.
            # The renderers beside the ray caster light as local shading or as the medium.
            # A method that adds light (translucency's indirect light) is not darker than local
            # shading, and its unobstructed frame (its own shading rule) is brighter still.
            measurement = None
            factor = 1.0
        else:
            measurement = measure_auto_exposure(self.renderer, self.volume, self.illuminator)
            factor = measurement.factor
        self.exposure_measurement = measurement
        changed = factor != self.auto_exposure_factor
        self.auto_exposure_factor = factor
        self._apply_exposure()
        return changed

    def _effective_tf(self, channel: Channel):
        """The 1-D transfer function ``channel`` is drawn with: its own or its link's, with
        the channel's gamma baked in (vtkvol.model.gamma)."""
        return shown_tf(self.model, self.model.channels.index(channel))

    def _isosurface_value(self) -> float:
        value = self.model.render.isosurface_value
        if value is not None:
            return value
        lo, hi = self.model.channels[0].tf.value_span
        return 0.5 * (lo + hi)

    def _apply_blending(self) -> None:
        render = self.model.render
        self.mapper.SetBlendMode(_BLEND[render.blend_mode])
        mixing = render.channel_mixing == "composite" and len(self.model.channels) > 1
        sp = self.volume.GetShaderProperty()
        if mixing:
            sp.AddFragmentShaderReplacement(_VTK_MIX_LINE, False, _ABSORBER_MIX_LINE, False)
        else:
            sp.ClearFragmentShaderReplacement(_VTK_MIX_LINE, False)

    def _apply_sampling(self) -> None:
        render = self.model.render
        step = render.interactive_sample_distance if self._interactive else render.sample_distance
        self.mapper.SetSampleDistance(step * self._min_spacing())
        self.mapper.SetImageSampleDistance(
            render.interactive_image_factor if self._interactive else 1.0
        )
        self._apply_table_steps()  # 2-D tables hold alpha per ray step

    def _apply_illumination(self) -> None:
        assert self.illuminator is not None
        illum = self.model.illumination
        self.illuminator.set_method(illum.method)
        self.illuminator.set_parameters(**illum.values_for())

    def _apply_crop(self) -> None:
        if self._image is None:
            return
        crop = self.model.crop
        if crop.x is None and crop.y is None and crop.z is None:
            self.mapper.SetCropping(0)
            return
        self.mapper.SetCropping(1)
        self.mapper.SetCroppingRegionPlanes(*crop.as_bounds(self.bounds))
        self.mapper.SetCroppingRegionFlagsToSubVolume()

    def clip_plane_origin(self) -> tuple[float, float, float]:
        """The clipping plane's origin in world µm: the model's, or the data's centre."""
        origin = self.model.clip_plane.origin
        if origin is not None:
            return origin
        b = self.bounds
        return ((b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2)

    def _apply_clip_plane(self) -> None:
        """The mapper's one clipping plane follows ``model.clip_plane``; the illumination reads
        the mapper's planes, so what is clipped away casts no shadow."""
        self.mapper.RemoveAllClippingPlanes()
        clip = self.model.clip_plane
        if not clip.enabled or self._image is None:
            return
        plane = vtk.vtkPlane()
        plane.SetOrigin(*self.clip_plane_origin())
        plane.SetNormal(*clip.normal)
        self.mapper.AddClippingPlane(plane)

    def _apply_slice_weights(self) -> None:
        assert self.illuminator is not None
        weights = self.model.slice_weights
        if weights.is_identity:
            self.illuminator.set_slice_weights(None)
            return
        grid = np.linspace(0.0, 1.0, WEIGHT_SAMPLES)
        table = np.stack(
            [
                np.interp(grid, *np.asarray(points, dtype=np.float64).T)
                for points in (weights.x, weights.y, weights.z)
            ]
        )
        self.illuminator.set_slice_weights(table.astype(np.float32))

    def _apply_camera(self) -> None:
        cam = self.renderer.GetActiveCamera()
        state = self.model.camera
        if state.position is None or state.focal_point is None:
            self.reset_camera()
            return
        cam.SetPosition(*state.position)
        cam.SetFocalPoint(*state.focal_point)
        cam.SetViewUp(*state.view_up)
        cam.SetViewAngle(state.view_angle)
        cam.SetParallelProjection(int(state.parallel_projection))
        cam.SetParallelScale(state.parallel_scale)
        self.renderer.ResetCameraClippingRange()

    def _min_spacing(self) -> float:
        if self.data is None:
            return 1.0
        return float(min(self.data.voxel_size_um))

    # -- illumination feedback ------------------------------------------------------------------
    def _on_illumination_error(self, message: str) -> None:
        """The technique failed and the host shows local shading: make the model say so (the
        dock then shows the truth, and the next edit does not rebuild the broken shader)."""
        assert self.illuminator is not None
        shown = self.illuminator.method
        if self.model.illumination.method != shown:
            with self.engine_edit():
                self.model.illumination.method = shown
        self.error.emit(message)

    def precompute(self, progress: Callable[[float], bool] | None = None) -> bool:
        """Bring the illumination's precomputed light up to date now, in chunks, outside a
        frame (:meth:`Illuminator.precompute`; ``progress(fraction)`` runs between chunks and
        returns False to cancel). A cancelled precomputation shows local shading and the
        model says so (through :attr:`engine_edit`, like a failure); returns False then."""
        illuminator = self.illuminator
        if illuminator is None:
            return True
        if illuminator.precompute(progress):
            return True
        if not illuminator.closed and self.model.illumination.method != illuminator.method:
            with self.engine_edit():
                self.model.illumination.method = illuminator.method
        return False

    def _on_illumination_progress(self, iteration: int, converged: bool) -> None:
        self.progress.emit(iteration, converged)
        # Ask for the next refinement frame (wants_frame is also False once the technique
        # failed). Without a scheduler (scripts, render_image) rendering from inside this frame
        # would recurse, so the caller drives refinement with Illuminator.converge().
        assert self.illuminator is not None
        if self.illuminator.wants_frame and self._request_render is not None:
            self._request_render()

    # -- camera ---------------------------------------------------------------------------------
    def visible_bounds(self) -> tuple[float, float, float, float, float, float]:
        """World bounds (µm) of what is visible: voxels with non-zero opacity inside the crop
        box (:func:`vtkvol.engine.framing.visible_bounds`); the data's box when nothing is."""
        if self.data is None:
            return self.bounds
        found = visible_bounds(self.data, self.model)
        return found if found is not None else self.model.crop.as_bounds(self.bounds)

    def reset_camera(self, *, azimuth: float = 30.0, elevation: float = 20.0) -> None:
        """Frame the data's box, or with ``framing="visible"`` the visible content
        (:meth:`visible_bounds`), from the front (−y), z up, then rotate by the angles (°)."""
        b = self.visible_bounds() if self.framing == "visible" else self.bounds
        center = np.array([(b[0] + b[1]) / 2, (b[2] + b[3]) / 2, (b[4] + b[5]) / 2])
        cam = self.renderer.GetActiveCamera()
        cam.SetParallelProjection(int(self.model.camera.parallel_projection))
        cam.SetFocalPoint(*center)
        cam.SetPosition(*(center - np.array([0.0, 1.0, 0.0])))
        cam.SetViewUp(0.0, 0.0, 1.0)
        cam.Azimuth(azimuth)
        cam.Elevation(elevation)
        cam.OrthogonalizeViewUp()
        self.renderer.ResetCamera(*b)
        self.sync_camera_to_model()

    def orbit(self, azimuth: float = 0.0, elevation: float = 0.0) -> None:
        """Rotate the camera around the focal point (degrees) and store it in the model."""
        cam = self.renderer.GetActiveCamera()
        cam.Azimuth(azimuth)
        cam.Elevation(elevation)
        cam.OrthogonalizeViewUp()
        self.renderer.ResetCameraClippingRange()
        self.sync_camera_to_model()

    def sync_camera_to_model(self) -> None:
        """Copy the VTK camera (moved by the interactor) into ``model.camera``."""
        cam = self.renderer.GetActiveCamera()
        self._syncing_camera = True
        try:
            self.model.camera.update(
                {
                    "position": tuple(cam.GetPosition()),
                    "focal_point": tuple(cam.GetFocalPoint()),
                    "view_up": tuple(cam.GetViewUp()),
                    "view_angle": float(cam.GetViewAngle()),
                    "parallel_projection": bool(cam.GetParallelProjection()),
                    "parallel_scale": max(float(cam.GetParallelScale()), 1e-9),
                }
            )
        finally:
            self._syncing_camera = False

    # -- interaction ----------------------------------------------------------------------------
    def set_interactive(self, interactive: bool) -> None:
        """Coarser sampling while the camera moves (seed 002's "Reduce"); full when it stops."""
        if interactive != self._interactive:
            self._interactive = interactive
            self._apply_sampling()

    @property
    def interactive(self) -> bool:
        return self._interactive

    def request_render(self) -> None:
        if self._request_render is not None:
            self._request_render()
        else:
            rw = self.renderer.GetRenderWindow()
            if rw is not None:
                rw.Render()

    # -- teardown -------------------------------------------------------------------------------
    def close(self) -> None:
        """Release GL resources and remove the volume (call while the window still exists)."""
        self.model.changed.disconnect(self._on_model_changed)
        self.overlays.close()
        if self.illuminator is not None:
            self.illuminator.release()
            self.illuminator = None
        rw = self.renderer.GetRenderWindow()
        if rw is not None:
            self.mapper.ReleaseGraphicsResources(rw)
        self.renderer.RemoveVolume(self.volume)
        self._keepalive = None


def _to_image(data: VolumeData) -> tuple[vtk.vtkImageData, np.ndarray]:
    """``vtkImageData`` for ``data``: zero-copy for one contiguous channel; channels interleaved
    (a copy VTK requires) otherwise. NaN/inf are replaced by the finite minimum (copy).
    Returns the image and the numpy buffer it reads, which the caller must keep alive."""
    arr = data.array
    c, nz, ny, nx = arr.shape
    if arr.dtype.kind == "f" and not np.isfinite(arr).all():
        lo = min(data.channel_range(i)[0] for i in range(c))
        arr = np.nan_to_num(np.asarray(arr), nan=lo, posinf=lo, neginf=lo)
    if c == 1:
        flat = np.ascontiguousarray(arr[0]).reshape(-1)
    else:
        # One channel at a time into the interleaved buffer: 5× faster than a copy of the
        # moved axes (18 against 97 ms for 2 × 100 × 256 × 256 uint16), and it runs on the GUI
        # thread at every time step.
        interleaved = np.empty((nz, ny, nx, c), dtype=arr.dtype)
        for i in range(c):
            interleaved[..., i] = arr[i]
        flat = interleaved.reshape(-1, c)
    image = vtk.vtkImageData()
    image.SetDimensions(nx, ny, nz)
    image.SetSpacing(*(float(s) for s in data.voxel_size_um))
    image.SetOrigin(0.0, 0.0, 0.0)
    scalars = numpy_to_vtk(flat, deep=False)
    scalars.SetName("intensity")
    image.GetPointData().SetScalars(scalars)
    return image, flat
