"""quality= presets of render and render_volume: each preset is exactly the knobs it names
(the same image as those knobs given by hand), the presets order by error against a fine
reference, and bad or conflicting input is a ValueError."""

import numpy as np
import pytest

import matrixtree
from matrixtree import scenes


@pytest.fixture(scope="module")
def mesh():
    return scenes.default_scene(resolution=0.3)


@pytest.fixture(scope="module")
def ball():
    x, y, z = np.mgrid[-1:1:24j, -1:1:20j, -1:1:22j]
    return np.clip(1 - np.sqrt(x * x + y * y + z * z), 0, None).astype(np.float32)


def test_render_presets_are_their_triangle_tests(mesh):
    for quality, test in (("exact", "watertight"), ("balanced", "moller-trumbore"), ("fast", "moller-trumbore")):
        a = matrixtree.render(mesh, size=(48, 40), quality=quality)
        b = matrixtree.render(mesh, size=(48, 40), triangle_test=test)
        np.testing.assert_array_equal(a["rgb"], b["rgb"])
        np.testing.assert_array_equal(a["depth"], b["depth"])


def test_volume_presets_are_their_knobs_and_order_by_error(ball):
    kw = dict(size=(40, 32), spacing=(0.5, 0.5, 0.5))
    half = 0.25
    settings = {"exact": dict(sample_distance=0.25 * half, early_termination=1.0),
                "balanced": dict(),
                "fast": dict(sample_distance=2 * half, image_sample_distance=2.0, early_termination=0.95)}
    ref = matrixtree.render_volume(ball, sample_distance=half / 16, early_termination=1.0, double_precision=True, **kw)
    errors = {}
    for quality, knobs in settings.items():
        img = matrixtree.render_volume(ball, quality=quality, **kw)
        np.testing.assert_array_equal(img, matrixtree.render_volume(ball, **knobs, **kw))
        errors[quality] = float(np.abs(img - ref).mean())
    assert errors["exact"] < errors["balanced"] < errors["fast"]


@pytest.mark.parametrize("call, extra", [
    ("render", dict(triangle_test="watertight")),
    ("render_volume", dict(sample_distance=0.1)),
    ("render_volume", dict(image_sample_distance=2.0)),
    ("render_volume", dict(early_termination=0.9)),
])
def test_a_preset_and_one_of_its_knobs_are_refused(mesh, ball, call, extra):
    data = mesh if call == "render" else ball
    with pytest.raises(ValueError, match="not both"):
        getattr(matrixtree, call)(data, size=(16, 16), quality="fast", **extra)


@pytest.mark.parametrize("call", ["render", "render_volume"])
def test_an_unknown_quality_is_refused(mesh, ball, call):
    data = mesh if call == "render" else ball
    with pytest.raises(ValueError, match="quality must be one of"):
        getattr(matrixtree, call)(data, size=(16, 16), quality="best")
