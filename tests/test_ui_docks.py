"""Every dock in both directions (changing the model updates the view; changing the view
updates the model) and a rendered pixel change for each. Needs X (pytest-xvfb) and GL."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from vtkvol.io import VolumeData, confocal_phantom
from vtkvol.model.defaults import contrast_limits
from vtkvol.ui.docks import base as dock_base
from vtkvol.ui.docks.lights import AUTO_CHOICE, angles_to_direction
from vtkvol.ui.undo import apply_state

pytestmark = pytest.mark.gui


# -- helpers ------------------------------------------------------------------------------------
def shot(window) -> np.ndarray:
    return window.viewport.screenshot().astype(np.float64)


def foreground(image: np.ndarray, window) -> np.ndarray:
    """Mask of pixels that are clearly not the background colour."""
    bg = np.array(window.model.render.background) * 255.0
    return np.abs(image - bg).max(axis=-1) > 12


def at(editor, x: float, y: float, curve: str) -> QPoint:
    return editor.to_pixel(x, y, editor.curve(curve)).toPoint()


def stroke_along_bottom(qtbot, editor, curve: str) -> None:
    """Curve mode: press at the left end at zero and draw to the right end at zero."""
    lo, hi = editor.domain
    qtbot.mousePress(editor, Qt.MouseButton.LeftButton, pos=at(editor, lo, 0.0, curve))
    for t in np.linspace(0.0, 1.0, 12):
        qtbot.mouseMove(editor, at(editor, lo + t * (hi - lo), 0.0, curve))
    qtbot.mouseRelease(editor, Qt.MouseButton.LeftButton, pos=at(editor, hi, 0.0, curve))


@pytest.fixture(scope="module")
def pristine() -> dict[str, Any]:
    """The model state every test starts from, taken when the module's window first shows
    the data (filled by ``window``)."""
    return {}


@pytest.fixture
def window(opened_window, pristine):
    """The opened window in the same model state before every test, with a clean undo
    history. The state is set rather than undone, so a test that failed half-way, or a
    change the undo stack does not record, cannot leak into the tests after it: the outcome
    does not depend on test order (the window itself is shared because opening is slow)."""
    model = opened_window.model
    if not pristine:
        pristine.update(model.copy_state())
    apply_state(model, pristine)
    opened_window.recorder.reset()
    yield opened_window
    opened_window.recorder.reset()


@pytest.fixture
def pick(monkeypatch):
    """Answer the colour dialog with the colour in ``pick.rgb``."""

    class Answer:
        rgb = (1.0, 0.0, 0.0)

    monkeypatch.setattr(dock_base, "pick_color", lambda parent, initial, title: Answer.rgb)
    return Answer


# -- transfer function ------------------------------------------------------------------------
def test_tf_model_updates_view(window):
    dock, tf = window.tf_dock, window.model.channels[0].tf
    lo, hi = tf.window_range
    tf.opacity = [(lo, 0.0), ((lo + hi) / 2, 0.3), (hi, 0.9)]
    assert dock.editor.points("opacity") == tf.opacity
    tf.set_window(lo + 100, hi - 100)
    assert dock.window_min.value() == lo + 100 and dock.window_max.value() == hi - 100
    assert dock.window_slider.value() == (lo + 100, hi - 100)
    assert dock.editor.domain == (lo + 100, hi - 100)
    tf.colors = [(lo, 0.0, 0.0, 0.0), (hi, 0.0, 1.0, 0.0)]
    assert dock.editor.points("green") == [(lo, 0.0), (hi, 1.0)]
    assert dock.editor.points("red") == [(lo, 0.0), (hi, 0.0)]
    assert dock.colorbar._colors == tf.colors


def test_tf_view_updates_model(window, qtbot):
    dock, tf = window.tf_dock, window.model.channels[0].tf
    assert dock.editor._histogram is not None and dock.editor._histogram.sum() > 0
    lo, hi = tf.window
    editor = dock.editor
    qtbot.mouseClick(editor, Qt.MouseButton.LeftButton,
                     pos=at(editor, lo + 0.9 * (hi - lo), 0.95, "opacity"))
    assert len(tf.opacity) == 3
    assert max(a for _, a in tf.opacity) == pytest.approx(0.95, abs=0.02)
    dock.window_min.setValue(lo + 50)
    assert tf.window == (lo + 50, hi)
    dock.window_full.click()
    assert tf.window == tf.window_range
    dock.log_opacity.click()
    assert editor.log_scale
    dock.log_opacity.click()
    dock.curve_buttons["green"].click()
    assert editor.active == "green"
    greens_before = len(editor.points("green"))
    qtbot.mouseClick(editor, Qt.MouseButton.LeftButton,
                     pos=at(editor, lo + 0.5 * (hi - lo), 1.0, "green"))
    assert len(editor.points("green")) == greens_before + 1
    assert tf.color_at(np.array([lo + 0.5 * (hi - lo)]))[0][1] == pytest.approx(1.0, abs=0.02)
    dock.curve_buttons["opacity"].click()
    action = next(a for a in dock.preset_menu.actions() if a.data() == "fluorescence-sharp")
    action.trigger()
    assert len(tf.opacity) >= 3  # the preset's shape, stretched over the same span


def test_tf_opacity_to_zero_darkens_and_undo_restores(window, qtbot):
    dock = window.tf_dock
    before = shot(window)
    assert foreground(before, window).mean() > 0.03
    dock.mode_curve.click()
    stroke_along_bottom(qtbot, dock.editor, "opacity")
    dock.mode_points.click()
    assert max(a for _, a in window.model.channels[0].tf.opacity) < 0.01
    assert window.recorder.stack.count() == 1  # one drag, one undo step
    dark = shot(window)
    assert foreground(dark, window).mean() < 0.005
    window.undo_action.trigger()
    assert np.abs(shot(window) - before).mean() < 1.0
    window.redo_action.trigger()
    assert foreground(shot(window), window).mean() < 0.005


def test_tf_colour_changes_the_mean_colour(window, qtbot, pick):
    dock, tf = window.tf_dock, window.model.channels[0].tf
    before = shot(window)
    lo, hi = tf.value_span
    pick.rgb = (0.1, 0.2, 1.0)
    for value in (lo, hi):
        dock.set_color_at(value, pick.rgb)  # what double-clicking the colour bar does
    x = dock.colorbar.bar_rect().left() + 0.5 * dock.colorbar.bar_rect().width()
    qtbot.mouseDClick(dock.colorbar, Qt.MouseButton.LeftButton,
                      pos=QPoint(int(x), dock.colorbar.BAR_HEIGHT // 2))
    assert any(c[1:] == (0.1, 0.2, 1.0) and lo < c[0] < hi for c in tf.colors)
    after = shot(window)
    mask = foreground(after, window)
    blue_minus_red_before = (before[..., 2] - before[..., 0])[foreground(before, window)].mean()
    blue_minus_red_after = (after[..., 2] - after[..., 0])[mask].mean()
    assert blue_minus_red_after > blue_minus_red_before + 10


def test_tf_save_and_load(window, tmp_path, dialogs):
    dock, tf = window.tf_dock, window.model.channels[0].tf
    saved = tf.copy_state()
    dock.save_tf(tmp_path / "mine.tf.json")
    dock.apply_preset("viridis")
    assert tf.copy_state() != saved
    dock.load_tf(tmp_path / "mine.tf.json")
    assert tf.colors == [tuple(c) for c in saved["colors"]]
    assert tf.opacity == [tuple(o) for o in saved["opacity"]]
    (tmp_path / "bad.tf.json").write_text('{"format": "something else"}')
    dock.load_tf(tmp_path / "bad.tf.json")
    assert "not a vtkvol transfer-function file" in dialogs[-1].informativeText()


# -- slice contribution -----------------------------------------------------------------------
def test_slice_weights_model_updates_view(window):
    dock, weights = window.slice_dock, window.model.slice_weights
    weights.x = [(0.0, 0.0), (0.5, 1.0), (1.0, 0.0)]
    assert dock.editor.points("x") == weights.x
    weights.update({"x": [(0.0, 1.0), (1.0, 1.0)]})
    assert dock.editor.points("x") == [(0.0, 1.0), (1.0, 1.0)]


def test_slice_weights_view_updates_model_and_the_image(window, qtbot):
    dock, weights = window.slice_dock, window.model.slice_weights
    before = shot(window)
    dock.axis_buttons["y"].click()
    assert dock.editor.active == "y"
    qtbot.mouseClick(dock.editor, Qt.MouseButton.LeftButton, pos=at(dock.editor, 0.5, 0.3, "y"))
    assert len(weights.y) == 3 and weights.y[1][1] == pytest.approx(0.3, abs=0.03)
    dock.reset_axis.click()
    assert weights.y == [(0.0, 1.0), (1.0, 1.0)]
    dock.axis_buttons["x"].click()
    dock.mode_curve.click()
    stroke_along_bottom(qtbot, dock.editor, "x")
    dock.mode_points.click()
    assert max(w for _, w in weights.x) < 0.01
    assert foreground(shot(window), window).mean() < 0.005  # weight 0: nothing drawn
    dock.reset_all.click()
    assert weights.is_identity
    assert np.abs(shot(window) - before).mean() < 1.0


# -- ranges -------------------------------------------------------------------------------------
def test_ranges_model_updates_view(window):
    dock, crop = window.ranges_dock, window.model.crop
    assert dock.full_range("x") == (0.0, 47.0)  # 48 voxels of 1 µm, centres 0…47
    crop.x = (5.0, 20.0)
    assert dock.lo_boxes["x"].value() == 5.0 and dock.hi_boxes["x"].value() == 20.0
    assert dock.sliders["x"].value() == (5.0, 20.0)
    crop.x = None
    assert dock.sliders["x"].value() == (0.0, 47.0)


def test_ranges_view_updates_model_and_the_image(window):
    dock, crop = window.ranges_dock, window.model.crop
    before = shot(window)
    dock.hi_boxes["x"].setValue(30.0)
    assert crop.x == (0.0, 30.0)
    dock.sliders["z"].setValue((4.0, 20.0))
    assert crop.z == (4.0, 20.0)
    dock.sliders["x"].setValue((20.0, 24.0))
    assert crop.x == (20.0, 24.0)
    narrow = shot(window)
    assert foreground(narrow, window).mean() < 0.5 * foreground(before, window).mean()
    dock.reset_button.click()
    assert (crop.x, crop.y, crop.z) == (None, None, None)
    dock.sliders["y"].setValue((0.0, 47.0))
    assert crop.y is None  # the full extent is stored as "no crop"


# -- channels -----------------------------------------------------------------------------------
def test_channels_model_updates_view(window):
    dock, channel = window.channels_dock, window.model.channels[0]
    row = dock.rows[0]
    channel.visible = False
    assert not row.visible.isChecked()
    channel.visible = True
    channel.color = (0.2, 0.4, 0.6)
    assert row.color.rgb() == (0.2, 0.4, 0.6)
    channel.tf.rescale(300.0, 1500.0)
    assert (row.minimum.value(), row.maximum.value()) == (300.0, 1500.0)
    window.model.render.blend_mode = "mip"
    assert dock.blend.currentData() == "mip"
    window.model.render.blend_mode = "isosurface"
    assert dock.iso_row.isVisibleTo(dock)
    window.model.render.blend_mode = "composite"
    assert not dock.iso_row.isVisibleTo(dock)


def test_channels_view_updates_model_and_the_image(window, pick):
    dock, channel = window.channels_dock, window.model.channels[0]
    row = dock.rows[0]
    before = shot(window)
    row.visible.click()
    assert channel.visible is False
    assert foreground(shot(window), window).mean() < 0.005  # the only channel is hidden
    row.visible.click()
    pick.rgb = (0.0, 0.3, 1.0)
    row.color.click()
    assert channel.color == (0.0, 0.3, 1.0)
    assert all(r <= g <= b for _, r, g, b in channel.tf.colors)  # the TF took the tint
    tinted = shot(window)
    assert tinted[..., 2][foreground(tinted, window)].mean() > (
        tinted[..., 0][foreground(tinted, window)].mean() + 20)
    row.minimum.setValue(500.0)
    assert channel.tf.value_span[0] == pytest.approx(500.0)
    row.auto.click()
    # Auto: the contrast a freshly opened channel gets (issue 15: they used to disagree).
    assert channel.tf.value_span == pytest.approx(contrast_limits(window.data, 0))
    dock.blend.setCurrentIndex(dock.blend.findData("mip"))
    assert window.model.render.blend_mode == "mip"
    mip = shot(window)
    assert np.abs(mip - before).mean() > 1.0
    dock.blend.setCurrentIndex(dock.blend.findData("composite"))


def test_channel_tf_link_with_two_channels(window, qtbot, small_volume_file):
    two = confocal_phantom((12, 24, 24), voxel_size_um=(1.0, 1.0, 2.0))
    window.show_volume(VolumeData.from_array(two.array, two.voxel_size_um, two.channel_names))
    try:
        dock = window.channels_dock
        assert len(dock.rows) == 2 and dock.mixing.isVisibleTo(dock)
        link = dock.rows[1].link
        link.setCurrentIndex(link.findData(0))
        assert window.model.channels[1].tf_linked_to == 0
        assert not dock.rows[1].minimum.isEnabled()
        window.tf_dock.set_channel(1)
        assert window.tf_dock.current_tf() is window.model.channels[0].tf
        assert window.tf_dock.link_label.isVisibleTo(window.tf_dock)
        window.model.channels[1].tf_linked_to = None
        assert link.currentData() is None
        window.tf_dock.set_channel(0)
    finally:
        with qtbot.waitSignal(window.dataShown, timeout=30_000):
            window.open_path(small_volume_file)


# -- lights and illumination ------------------------------------------------------------------
def test_lights_model_updates_view(window):
    dock = window.lights_dock
    light = window.model.lights[0]
    light.direction = angles_to_direction(30.0, 45.0)
    assert dock.azimuth.value() == pytest.approx(30.0) and dock.elevation.value() == 45.0
    light.intensity = 2.5
    assert dock.intensity.value() == 2.5
    light.color = (1.0, 0.5, 0.0)
    assert dock.color.rgb() == (1.0, 0.5, 0.0)
    light.kind = "point"
    assert all(b.isVisibleTo(dock) for b in dock.position_boxes)
    assert not dock.azimuth.isVisibleTo(dock)
    light.kind = "directional"
    window.model.lights = [*window.model.lights, type(light)()]
    assert dock.light_list.count() == 2


def test_lights_view_updates_model_and_the_image(window):
    dock = window.lights_dock
    lights = window.model.lights
    before = shot(window)
    dock.intensity.setValue(0.0)
    assert lights[0].intensity == 0.0
    unlit = shot(window)
    mask = foreground(before, window)
    assert unlit[mask].mean() < before[mask].mean() - 5  # only the ambient term is left
    dock.intensity.setValue(1.0)
    dock.azimuth.setValue(-90.0)
    assert lights[0].direction == pytest.approx(angles_to_direction(-90.0, dock.elevation.value()))
    dock.add_button.click()
    assert len(window.model.lights) == 2 and dock.light_list.currentRow() == 1
    item = dock.light_list.item(1)
    item.setCheckState(Qt.CheckState.Unchecked)
    assert window.model.lights[1].enabled is False
    dock.remove_button.click()
    assert len(window.model.lights) == 1
    dock.kind.setCurrentIndex(dock.kind.findData("point"))
    assert window.model.lights[0].kind == "point"
    dock.position_boxes[2].setValue(-500.0)
    assert window.model.lights[0].position[2] == -500.0


def test_illumination_method_and_generated_parameters(window):
    dock = window.lights_dock
    choices = [dock.method.itemData(i) for i in range(dock.method.count())]
    assert choices[0] == AUTO_CHOICE  # Auto first (tests/test_ui_auto_quality.py), then methods
    choices = choices[1:]
    assert "local" in choices and set(choices) <= set(dock.techniques)
    with_params = [n for n in choices if dock.techniques[n].parameters]
    if not with_params:
        pytest.skip("no installed technique declares parameters")
    name = with_params[0]
    spec = dock.techniques[name]
    dock.method.setCurrentIndex(dock.method.findData(name))
    assert window.model.illumination.method == name
    assert dock.description.text() == spec.description
    for param in spec.parameters:
        widget = dock.param_widget(param.name)
        assert widget.objectName() == f"param_{param.name}"
        assert param.doc in widget.toolTip()
    numeric = next(p for p in spec.parameters if p.kind == "float" and p.range is not None)
    widget = dock.param_widget(numeric.name)
    lo, hi = numeric.range
    target = lo + 0.5 * (hi - lo) if numeric.step is None else (
        lo + round(0.5 * (hi - lo) / numeric.step) * numeric.step)
    widget.spin.setValue(target)
    assert window.model.illumination.values_for(name)[numeric.name] == pytest.approx(target)
    window.model.illumination.set_value(numeric.name, lo)
    assert widget.value() == pytest.approx(lo)
    dock.method.setCurrentIndex(dock.method.findData("local"))
    assert window.model.illumination.method == "local"


def test_light_size_falloff_and_the_medium_material(window):
    dock = window.lights_dock
    dock.light_list.setCurrentRow(0)
    light = window.model.lights[0]
    assert light.kind == "directional" and dock.size.suffix() == "°"
    assert dock.falloff.isHidden()  # fall-off is for point lights
    dock.size.setValue(2.0)
    assert light.size == 2.0
    light.kind = "point"
    try:
        assert dock.size.suffix() == " µm" and not dock.falloff.isHidden()
        dock.falloff.setChecked(True)
        assert light.falloff == "inverse_square"
    finally:
        light.update({"kind": "directional", "size": 0.0, "falloff": "none"})
    assert dock.material_box.isHidden()  # local shading: surface model
    window.model.illumination.method = "convection_diffusion"
    try:
        assert not dock.material_box.isHidden()
        dock.phase_g.setValue(0.6)
        assert window.model.render.phase_g == pytest.approx(0.6)
        window.model.render.albedo = 0.5
        assert dock.albedo.value() == pytest.approx(0.5)
    finally:
        window.model.illumination.method = "local"
        window.model.render.update({"albedo": 1.0, "phase_g": 0.0})


def test_parameters_without_effect_are_hidden(window):
    """cone_traced's view-cone angle applies only in view_cone mode (applies_when)."""
    dock = window.lights_dock
    if "cone_traced" not in dock.techniques:
        pytest.skip("cone_traced not installed")
    window.model.illumination.method = "cone_traced"
    try:
        window.model.illumination.set_value("ao_mode", "baked_hemisphere")
        angle = dock.param_widget("ao_angle")
        resolution = dock.param_widget("ao_resolution")
        assert angle.isHidden() and not resolution.isHidden()
        window.model.illumination.set_value("ao_mode", "view_cone")
        assert not angle.isHidden() and resolution.isHidden()
    finally:
        window.model.illumination.set_value("ao_mode", "baked_hemisphere")
        window.model.illumination.method = "local"


def test_light_gizmo_drag_moves_the_light(window, qtbot):
    viewport = window.viewport
    window.lights_dock.light_list.setCurrentRow(0)
    assert viewport.gizmo.visible
    renderer = viewport.renderer
    handle = viewport.gizmo.handle_position()
    renderer.SetWorldPoint(*handle, 1.0)
    renderer.WorldToDisplay()
    x, y, _ = renderer.GetDisplayPoint()
    ratio = viewport.plotter.devicePixelRatioF()
    plotter = viewport.plotter
    start = QPoint(round(x / ratio), round(plotter.height() - y / ratio))
    direction = window.model.lights[0].direction
    qtbot.mousePress(plotter, Qt.MouseButton.LeftButton, pos=start)
    for step in range(1, 8):
        qtbot.mouseMove(plotter, start + QPoint(-12 * step, 6 * step))
    assert viewport.scene.interactive  # reduced quality while dragging
    qtbot.mouseRelease(plotter, Qt.MouseButton.LeftButton, pos=start + QPoint(-84, 42))
    assert window.model.lights[0].direction != pytest.approx(direction, abs=1e-3)
    qtbot.waitUntil(lambda: not viewport.scene.interactive, timeout=3000)


def test_tf_colormap_by_name(window, monkeypatch, dialogs):
    from vtkvol.ui.docks import transfer_function as tf_module

    dock, tf = window.tf_dock, window.model.channels[0].tf
    colormaps = next(a.menu() for a in dock.preset_menu.actions() if a.menu() is not None)
    ask = next(a for a in colormaps.actions() if a.text() == "By name…")
    answer = {"text": "twilight"}
    monkeypatch.setattr(tf_module.QInputDialog, "getText",
                        staticmethod(lambda *args, **kwargs: (answer["text"], True)))
    ask.trigger()
    assert len(tf.colors) == 9 and dialogs == []
    answer["text"] = "no-such-colormap"
    ask.trigger()
    assert dialogs[-1].text() == "Could not apply the preset “no-such-colormap”"
    assert "unknown preset" in dialogs[-1].informativeText()


def test_renderer_chooser_greys_unsupported_choices_with_the_reason(window, qtbot):
    dock = window.lights_dock
    combo = dock.renderer
    choices = [combo.itemData(i) for i in range(combo.count())]
    assert choices == ["raycast", "path_tracer", "half_angle", "slicing"]
    enabled = {n: combo.model().item(i).isEnabled() for i, n in enumerate(choices)}
    assert enabled == {"raycast": True, "path_tracer": True,
                       "half_angle": sum(1 for li in window.model.lights
                                         if li.enabled and li.intensity > 0) == 1,
                       "slicing": window.model.illumination.method == "local"}
    window.model.illumination.method = "shadow_volume"
    i = combo.findData("slicing")
    assert not combo.model().item(i).isEnabled()
    assert combo.itemData(i, Qt.ItemDataRole.ToolTipRole) == (
        "The slicing renderer shades with local lighting only; method 'shadow_volume' needs "
        "the raycast renderer")
    before = shot(window)
    combo.setCurrentIndex(combo.findData("path_tracer"))
    assert window.model.render.renderer == "path_tracer"
    assert not dock.material_box.isHidden()  # the path tracer draws the medium material
    qtbot.waitUntil(lambda: window.viewport.scene.illuminator.beside is not None, timeout=10_000)
    after = shot(window)
    assert np.abs(after - before).mean() > 1  # drawn by the path tracer now
    window.model.render.renderer = "raycast"
    assert combo.currentData() == "raycast"


def test_render_checkboxes_for_preintegration_and_adaptive_sampling(window) -> None:
    """The two ray-caster switches of issue 23 edit the model and follow it (sessions)."""
    from PySide6.QtWidgets import QCheckBox

    render = window.model.render
    pre = window.findChild(QCheckBox, "render_preintegration")
    adaptive = window.findChild(QCheckBox, "render_adaptive_sampling")
    assert pre is not None and adaptive is not None
    assert not pre.isChecked() and not adaptive.isChecked()
    pre.setChecked(True)
    assert render.preintegration is True and render.adaptive_sampling is False
    adaptive.setChecked(True)
    assert render.adaptive_sampling is True
    render.preintegration = False
    assert not pre.isChecked()
