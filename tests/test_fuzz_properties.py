"""Property tests (hypothesis) over every reader of user files: a mutated valid seed is
either read into a usable result or refused with one typed error naming the file, never
anything else (issue 16, "Must show" 1). Deterministic (``derandomize``) so CI is
repeatable; the open-ended search is ``benchmarks/fuzz.py``.
"""

from __future__ import annotations

import math
import random
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzz_support import make_seeds, mutate
from usdmotion.constants import MAX_ABS_VALUE
from usdmotion.errors import InputError, UsdMotionError

SETTINGS = dict(deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    return make_seeds(tmp_path_factory.mktemp("seeds"))


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    return tmp_path_factory.mktemp("cases")


mutation = st.tuples(st.integers(0, 2**32 - 1), st.binary(max_size=24), st.floats(0, 1))


def _mutated(seed: bytes, case) -> bytes:
    rng_seed, splice, where = case
    data = mutate(seed, random.Random(rng_seed))
    if splice and rng_seed % 4 == 0:  # hypothesis' own bytes, spliced in a quarter of the cases
        k = int(where * len(data))
        data = data[:k] + splice + data[k:]
    return data


def _assert_refused_cleanly(error: BaseException, path: Path, other: Path | None = None) -> None:
    assert isinstance(error, UsdMotionError), f"{type(error).__name__}: {error}"
    text = str(error)
    assert "\n" not in text.strip() and text.strip()
    if isinstance(error, InputError):
        assert error.path in (str(path), str(other)), error.path


def _assert_usable(motion) -> None:
    for a in (motion.offsets, motion.root_translation, motion.rotations, motion.joint_translations):
        if a is not None and a.size:
            assert np.all(np.abs(a) <= MAX_ABS_VALUE)
    if motion.n_frames:
        assert np.allclose(np.linalg.norm(motion.rotations, axis=-1), 1.0, atol=1e-3)
    assert 0 < motion.fps < math.inf and 0 < motion.meters_per_unit < math.inf


def _read_or_refuse(path: Path, skeleton: Path | None = None) -> None:
    """``path`` (with the ASF ``skeleton`` of an AMC) reads into a usable motion or is refused by
    a typed one-line error naming the mutated file, or the skeleton where the two no longer fit."""
    from usdmotion.io import read_motion

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # usdmotion's own warnings (e.g. --lenient) are allowed
        try:
            motion = read_motion(path, skeleton=skeleton)
        except Exception as exc:  # noqa: BLE001 - the property: only typed errors
            _assert_refused_cleanly(exc, path, skeleton)
            return
    _assert_usable(motion)


@pytest.mark.parametrize("kind, examples", [("bvh_small", 300), ("bvh", 150), ("usda", 150), ("usdc", 60)])
def test_mutated_motion_files_are_read_or_refused_cleanly(seeds, scratch, kind, examples):
    seed = seeds[kind].read_bytes()

    @settings(max_examples=examples, **SETTINGS)
    @given(case=mutation)
    def check(case):
        path = scratch / f"case{seeds[kind].suffix}"
        path.write_bytes(_mutated(seed, case))
        _read_or_refuse(path)

    check()


@pytest.mark.parametrize("kind, examples", [("asf", 300), ("amc", 300)])
def test_mutated_asf_and_amc_are_read_or_refused_cleanly(seeds, scratch, kind, examples):
    """A mutated ASF under the valid AMC, or a mutated AMC on the valid ASF (issue 16)."""
    seed = seeds[kind].read_bytes()

    @settings(max_examples=examples, **SETTINGS)
    @given(case=mutation)
    def check(case):
        path = scratch / f"case.{kind}"
        path.write_bytes(_mutated(seed, case))
        if kind == "asf":
            _read_or_refuse(seeds["amc"], skeleton=path)
        else:
            _read_or_refuse(path, skeleton=seeds["asf"])

    check()


def test_mutated_joint_maps_are_loaded_or_refused_cleanly(seeds, scratch):
    from usdmotion.ops.retarget.jointmap import load_joint_map

    seed = seeds["jointmap"].read_bytes()

    @settings(max_examples=300, **SETTINGS)
    @given(case=mutation)
    def check(case):
        path = scratch / "map.json"
        path.write_bytes(_mutated(seed, case))
        try:
            jmap = load_joint_map(path)
        except Exception as exc:  # noqa: BLE001
            _assert_refused_cleanly(exc, path)
            return
        assert all(math.isfinite(w) and w >= 0 for w in jmap.weights.values())

    check()


def test_mutated_segment_labels_are_loaded_or_refused_cleanly(seeds, scratch):
    from usdmotion.ops.segment.evaluate import load_labels

    seed = seeds["segments"].read_bytes()

    @settings(max_examples=300, **SETTINGS)
    @given(case=mutation)
    def check(case):
        path = scratch / "labels.json"
        path.write_bytes(_mutated(seed, case))
        try:
            labels = load_labels(path, first_frame=0)
        except Exception as exc:  # noqa: BLE001
            _assert_refused_cleanly(exc, path)
            return
        assert labels.cuts.dtype.kind == "i"

    check()


def test_mutated_camera_files_give_a_camera_or_a_clean_error(seeds, scratch):
    from usdmotion.render.camera import usd_camera_track

    seed = seeds["camera"].read_bytes()
    times = np.array([0.0, 0.5])

    @settings(max_examples=150, **SETTINGS)
    @given(case=mutation)
    def check(case):
        path = scratch / "cam.usda"
        path.write_bytes(_mutated(seed, case))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                track = usd_camera_track(str(path), times)
            except Exception as exc:  # noqa: BLE001
                _assert_refused_cleanly(exc, path)
                return
        assert track.poses.shape == (2, 4, 4)

    check()


numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6))


@settings(max_examples=400, **SETTINGS)
@given(width=st.integers(-10, 10**5), height=st.integers(-10, 10**5), fps=st.one_of(st.none(), numbers),
       speed=numbers, grid_scale=numbers, msaa=st.integers(-5, 64), quality=st.integers(-5, 100),
       start=st.one_of(st.none(), st.integers(-10, 10)), style=st.sampled_from(["body", "stick", "both", "", "x"]))
def test_render_options_are_accepted_only_inside_their_documented_ranges(width, height, fps, speed, grid_scale,
                                                                         msaa, quality, start, style):
    from usdmotion.render import MSAA_SAMPLES, STYLES, RenderOptions, check_options

    options = RenderOptions(width=width, height=height, fps=fps, speed=speed, grid_scale=grid_scale, msaa=msaa,
                            quality=quality, start=start, style=style)
    try:
        check_options(options)
    except UsdMotionError as exc:
        assert str(exc).strip() and "\n" not in str(exc)
        return
    assert 16 <= width <= 8192 and 16 <= height <= 8192 and style in STYLES and msaa in MSAA_SAMPLES
    assert 0 <= quality <= 51 and math.isfinite(speed) and speed > 0 and math.isfinite(grid_scale)
    assert fps is None or (math.isfinite(fps) and fps > 0)
    assert start is None or start >= 0
