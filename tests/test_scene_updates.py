"""The engine rebuilds only what a model edit changed (GL): zero spurious recomputes of the
illumination, per-channel transfer functions, failures and progress reported to the model."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import pytest

from vtkvol.engine import shaders
from vtkvol.engine.offscreen import make_render_window
from vtkvol.engine.scene import VolumeScene
from vtkvol.engine.technique import Technique
from vtkvol.io import VolumeData
from vtkvol.model.defaults import scene_for
from vtkvol.model.techniques import TechniqueSpec, register

pytestmark = pytest.mark.gl


@pytest.fixture
def two_channel_scene():
    import vtk

    arr = np.zeros((2, 24, 24, 24), np.uint8)
    arr[0, 6:18, 6:18, 6:18] = 200
    arr[1, 4:10, 4:20, 4:20] = 150
    data = VolumeData.from_array(arr, (1.0, 1.0, 1.0), ["a", "b"])
    model = scene_for(data)
    model.illumination.method = "shadow_volume"
    model.render.sample_distance = 1.0
    rw = make_render_window((64, 64))
    renderer = vtk.vtkRenderer()
    rw.AddRenderer(renderer)
    scene = VolumeScene(renderer, model, data, request_render=lambda: None)
    rw.Render()
    yield rw, scene, model
    scene.close()
    rw.Finalize()


def recomputes(scene: VolumeScene) -> int:
    return scene.illuminator.technique.stats()["recomputes"]


@pytest.mark.parametrize(
    "edit",
    [
        lambda m: setattr(m.render, "background", (1.0, 1.0, 1.0)),
        lambda m: setattr(m.render, "jitter", not m.render.jitter),
        lambda m: setattr(m.channels[1], "name", "renamed"),
        lambda m: setattr(m.channels[0], "color", (0.2, 0.4, 0.6)),
        lambda m: setattr(m.lights[0], "intensity", 2.5),
        lambda m: setattr(m.lights[0], "color", (1.0, 0.8, 0.6)),
        lambda m: setattr(m.render, "ambient", 0.1),
        lambda m: setattr(m.channels[0].tf, "window", (10.0, 90.0)),
    ],
    ids=["background", "jitter", "channel_name", "channel_tint", "light_intensity",
         "light_colour", "ambient", "tf_window"],
)
def test_edits_that_do_not_change_opacity_or_light_geometry_recompute_nothing(
        two_channel_scene, edit):
    rw, scene, model = two_channel_scene
    before = recomputes(scene)
    edit(model)
    rw.Render()
    rw.Render()
    assert recomputes(scene) == before


def test_camera_moves_recompute_nothing(two_channel_scene):
    rw, scene, _model = two_channel_scene
    before = recomputes(scene)
    scene.orbit(40.0, 10.0)
    rw.Render()
    assert recomputes(scene) == before


def test_a_tf_edit_on_channel_1_rebuilds_channel_1_only(two_channel_scene):
    rw, scene, model = two_channel_scene
    prop = scene.property
    mtimes = [prop.GetScalarOpacity(c).GetMTime() for c in range(2)]
    before = recomputes(scene)
    model.channels[1].tf.opacity = [(0.0, 0.0), (255.0, 0.9)]
    rw.Render()
    assert prop.GetScalarOpacity(0).GetMTime() == mtimes[0]
    assert prop.GetScalarOpacity(1).GetMTime() > mtimes[1]
    assert recomputes(scene) == before + 1
    assert prop.GetScalarOpacity(1).GetValue(255.0) == pytest.approx(0.9)


def test_a_linked_channel_follows_its_source_and_leaves_when_unlinked(two_channel_scene):
    rw, scene, model = two_channel_scene
    prop = scene.property
    model.channels[1].tf_linked_to = 0
    rw.Render()
    assert prop.GetScalarOpacity(1).GetValue(200.0) == pytest.approx(
        prop.GetScalarOpacity(0).GetValue(200.0))
    mtime = prop.GetScalarOpacity(1).GetMTime()
    before = recomputes(scene)
    model.channels[0].tf.opacity = [(0.0, 0.0), (255.0, 0.7)]
    rw.Render()
    assert prop.GetScalarOpacity(1).GetMTime() > mtime  # the follower was rebuilt as well
    assert prop.GetScalarOpacity(1).GetValue(255.0) == pytest.approx(0.7)
    assert recomputes(scene) == before + 1  # both functions changed: still one recompute
    model.channels[1].tf_linked_to = None
    rw.Render()
    assert prop.GetScalarOpacity(1).GetValue(255.0) == pytest.approx(
        model.channels[1].tf.opacity[-1][1])


def test_light_geometry_and_visibility_edits_do_recompute(two_channel_scene):
    rw, scene, model = two_channel_scene
    before = recomputes(scene)
    model.lights[0].direction = (1.0, 0.0, 0.0)
    rw.Render()
    model.channels[0].visible = False
    rw.Render()
    assert recomputes(scene) == before + 2
    assert scene.property.GetComponentWeight(0) == 0.0


class Broken(Technique):
    SPEC = TechniqueSpec(name="broken_in_scene", label="Broken", engine=f"{__name__}:Broken")
    SHADER: ClassVar[str] = "broken.glsl"
    builds: ClassVar[int] = 0

    def sections(self, values: Mapping[str, Any]) -> list[shaders.Section]:
        type(self).builds += 1
        return shaders.parse("//@inject //VTK::ComputeLighting::Dec pre before\n"
                             "float vv_light_visibility(int l, vec3 p, vec3 d) { return x; }\n",
                             "broken.glsl")


def test_a_failed_technique_is_set_back_in_the_model_and_not_retried(two_channel_scene):
    rw, scene, model = two_channel_scene
    messages: list[str] = []
    scene.error.connect(messages.append)
    with register(Broken.SPEC):
        model.illumination.method = "broken_in_scene"
        rw.Render()
        rw.Render()
        assert model.illumination.method == "local"
        assert len(messages) == 1 and "'Broken'" in messages[0]
        builds = Broken.builds
        model.render.background = (0.5, 0.5, 0.5)  # an unrelated edit
        rw.Render()
        assert Broken.builds == builds and model.illumination.method == "local"
        assert len(messages) == 1
        model.illumination.method = "broken_in_scene"  # the user picks it again: one retry
        rw.Render()
        rw.Render()
        assert Broken.builds > builds and len(messages) == 2
        assert model.illumination.method == "local"


class Refining(Technique):
    SPEC = TechniqueSpec(name="refining_scene", label="Refining",
                         engine=f"{__name__}:Refining", capabilities={"progressive"})
    SHADER: ClassVar[str] = ""

    def sections(self, values: Mapping[str, Any]) -> list[shaders.Section]:
        return []

    def prepare(self, changes, values) -> None:
        self.iteration = 1 if changes.reset_accumulation else self.iteration + 1
        self.converged = self.iteration >= 5


def test_progress_is_reported_and_frames_are_requested_until_converged():
    import vtk

    arr = np.zeros((1, 16, 16, 16), np.uint8)
    arr[0, 4:12, 4:12, 4:12] = 200
    data = VolumeData.from_array(arr, (1.0, 1.0, 1.0), ["a"])
    model = scene_for(data)
    rw = make_render_window((48, 48))
    renderer = vtk.vtkRenderer()
    rw.AddRenderer(renderer)
    pending = [0]

    def drain() -> int:
        """What the app's coalescing timer does: render once per batch of requests, until no
        one asks any more. Returns the number of frames rendered."""
        frames = 0
        while pending[0] and frames < 20:
            pending[0] = 0
            rw.Render()
            frames += 1
        return frames

    with register(Refining.SPEC):
        model.illumination.method = "refining_scene"
        scene = VolumeScene(renderer, model, data,
                            request_render=lambda: pending.__setitem__(0, pending[0] + 1))
        progress: list[tuple[int, bool]] = []
        scene.progress.connect(lambda i, done: progress.append((i, done)))
        assert drain() == 5  # one frame asked for by showing the data, four by refinement
        assert progress == [(1, False), (2, False), (3, False), (4, False), (5, True)]
        assert not scene.illuminator.wants_frame
        scene.orbit(30.0, 0.0)
        assert drain() == 1
        assert progress[-1] == (6, True)  # the camera moved: refinement kept, not restarted
        progress.clear()
        model.channels[0].tf.opacity = [(0.0, 0.0), (255.0, 0.5)]
        assert drain() == 5  # a TF edit restarts refinement, which again runs by itself
        assert [i for i, _ in progress] == [1, 2, 3, 4, 5] and progress[-1][1]
        scene.close()
    rw.Finalize()
