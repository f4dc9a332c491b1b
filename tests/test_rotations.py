"""Rotation conventions checked against SciPy (an independent implementation)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from usdmotion import quat_planes as Q
from usdmotion import rotations as R

ORDERS = R.EULER_ORDERS
SHAPES = [(), (1,), (3, 1, 2)]


def random_angles(shape, rng, keep_off_gimbal=True):
    angles = rng.uniform(-np.pi, np.pi, size=shape + (3,))
    if keep_off_gimbal:  # middle angle away from ±90°
        angles[..., 1] = rng.uniform(-1.3, 1.3, size=shape)
    return angles


def same_rotation(q1, q2, tol=1e-12):
    return np.all(np.abs(np.abs(np.sum(q1 * q2, axis=-1)) - 1.0) < tol)


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("shape", SHAPES)
def test_euler_to_quat_matches_scipy_intrinsic(order, shape):
    rng = np.random.default_rng(7)
    angles = random_angles(shape, rng)
    ours = R.euler_to_quat(angles, order)
    assert ours.shape == shape + (4,)
    theirs = Rotation.from_euler(order, angles.reshape(-1, 3)).as_quat(scalar_first=True).reshape(ours.shape)
    assert same_rotation(ours, theirs, 1e-12)


@pytest.mark.parametrize("order", ORDERS)
def test_bvh_channel_order_is_matrix_product_in_listed_order(order):
    # "Zrotation Xrotation Yrotation" means R = Rz @ Rx @ Ry (column vectors)
    angles = np.array([0.3, -0.7, 1.1])
    expected = np.eye(3)
    for axis, angle in zip(order, angles):
        expected = expected @ Rotation.from_rotvec(angle * np.eye(3)["XYZ".index(axis)]).as_matrix()
    assert np.allclose(R.quat_to_matrix(R.euler_to_quat(angles, order)), expected, atol=1e-14)


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("shape", SHAPES)
def test_quat_to_euler_round_trip(order, shape):
    rng = np.random.default_rng(11)
    angles = random_angles(shape, rng)
    q = R.euler_to_quat(angles, order)
    back = R.quat_to_euler(q, order, reference=angles)
    assert np.allclose(back, angles, atol=1e-10)


@pytest.mark.parametrize("order", ORDERS)
def test_reference_selects_equivalent_triples(order):
    rng = np.random.default_rng(3)
    angles = random_angles((50,), rng)
    alternative = angles + np.array([np.pi, 0.0, np.pi])
    alternative[:, 1] = np.pi - angles[:, 1]
    shifted = alternative + 2 * np.pi * rng.integers(-2, 3, size=alternative.shape)
    q = R.euler_to_quat(shifted, order)
    assert same_rotation(q, R.euler_to_quat(angles, order), 1e-10)  # truly equivalent
    assert np.allclose(R.quat_to_euler(q, order, reference=shifted + 0.01), shifted, atol=1e-9)
    assert np.allclose(R.quat_to_euler(q, order, reference=angles - 0.01), angles, atol=1e-9)


def test_quat_to_euler_without_reference_is_continuous_in_time():
    t = np.linspace(0, 4 * np.pi, 400)  # Z angle winds twice around
    angles = np.stack([t, 0.2 * np.sin(t), 0.1 * np.cos(t)], axis=1)
    back = R.quat_to_euler(R.euler_to_quat(angles, "ZXY"), "ZXY")
    assert np.max(np.abs(np.diff(back, axis=0))) < 0.1
    assert np.allclose(back, angles, atol=1e-9)


def test_quat_algebra_against_scipy():
    rng = np.random.default_rng(5)
    a = Rotation.random(20, random_state=1)
    b = Rotation.random(20, random_state=2)
    qa, qb = a.as_quat(scalar_first=True), b.as_quat(scalar_first=True)
    assert same_rotation(R.quat_mul(qa, qb), (a * b).as_quat(scalar_first=True))
    v = rng.normal(size=(20, 3))
    assert np.allclose(R.quat_rotate(qa, v), a.apply(v), atol=1e-12)
    assert np.allclose(R.quat_to_matrix(qa), a.as_matrix(), atol=1e-12)
    assert same_rotation(R.matrix_to_quat(a.as_matrix()), qa)
    assert np.allclose(R.quat_log(qa), a.as_rotvec(), atol=1e-10)
    assert same_rotation(R.quat_exp(a.as_rotvec()), qa)
    assert same_rotation(R.quat_mul(qa, R.quat_conjugate(qa)), np.tile([1.0, 0, 0, 0], (20, 1)))


def test_slerp_matches_scipy():
    key = Rotation.random(2, random_state=9)
    t = np.linspace(0, 1, 11)
    theirs = Slerp([0, 1], key)(t).as_quat(scalar_first=True)
    q0, q1 = key.as_quat(scalar_first=True)
    ours = R.quat_slerp(np.broadcast_to(q0, (11, 4)), np.broadcast_to(q1, (11, 4)), t)
    assert same_rotation(ours, theirs, 1e-10)


def test_quat_between_maps_direction_including_opposite():
    rng = np.random.default_rng(2)
    u = rng.normal(size=(30, 3))
    v = rng.normal(size=(30, 3))
    v[0] = -u[0]  # opposite directions
    q = R.quat_between(u, v)
    mapped = R.quat_rotate(q, u / np.linalg.norm(u, axis=1, keepdims=True))
    assert np.allclose(mapped, v / np.linalg.norm(v, axis=1, keepdims=True), atol=1e-9)


def test_small_angle_branches_are_accurate_and_grad_safe():
    jax = pytest.importorskip("jax")
    jnp = jax.numpy
    tiny = np.array([1e-10, -2e-10, 3e-10])
    assert np.allclose(R.quat_exp(tiny), [1.0, *(0.5 * tiny)], atol=1e-15)
    assert np.allclose(R.quat_log(R.quat_exp(tiny)), tiny, atol=1e-18)
    grad = jax.grad(lambda v: jnp.sum(R.quat_exp(v) * jnp.array([0.3, 1.0, -2.0, 0.5])))(jnp.zeros(3))
    assert np.all(np.isfinite(np.asarray(grad)))
    # d/dv of the vector part at 0 is 0.5 * weights
    assert np.allclose(np.asarray(grad), 0.5 * np.array([1.0, -2.0, 0.5]), atol=1e-6)


def test_numpy_and_jax_agree():
    jax = pytest.importorskip("jax")
    jnp = jax.numpy
    rng = np.random.default_rng(4)
    angles = random_angles((8,), rng)
    q_np = R.euler_to_quat(angles, "YZX")
    q_jx = np.asarray(R.euler_to_quat(jnp.asarray(angles), "YZX"))
    assert np.allclose(q_np, q_jx, atol=1e-6)  # JAX defaults to float32


def test_bad_order_is_a_value_error():
    with pytest.raises(ValueError, match="Euler order"):
        R.euler_to_quat(np.zeros(3), "XXY")


def test_one_hamilton_product_for_every_layout():
    """wxyz-last (quat_mul), component tuples (hamilton: forward kinematics) and component
    planes (quat_planes.mul: the editing kernels) give the same bits, and SciPy's rotation."""
    rng = np.random.default_rng(11)
    a, b = rng.normal(size=(2, 300, 4))
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    b /= np.linalg.norm(b, axis=-1, keepdims=True)
    product = R.quat_mul(a, b)
    scipy = (Rotation.from_quat(a[:, [1, 2, 3, 0]]) * Rotation.from_quat(b[:, [1, 2, 3, 0]])).as_quat()
    assert same_rotation(product, scipy[:, [3, 0, 1, 2]])
    assert np.array_equal(np.stack(R.hamilton(a.T, b.T), axis=-1), product)
    assert np.array_equal(Q.from_c(Q.mul(Q.to_c(a), Q.to_c(b))), product)
    assert np.array_equal(Q.from_c(Q.mul(Q.to_c(a), Q.to_c(b[:1]))), R.quat_mul(a, b[:1]))  # broadcasting


@pytest.mark.parametrize("shapes", [((523, 3), (523, 3)), ((40, 1, 3), (40, 7, 3)), ((3,), (5, 3)), ((4, 3), (3,))])
def test_cross_is_numpys_bit_for_bit_and_follows_jax(shapes):
    """``rotations.cross`` (NumPy's values without its axis bookkeeping) against ``np.cross``
    on broadcasting shapes and both float widths, and ``jnp.cross`` for JAX arrays."""
    import jax.numpy as jnp

    rng = np.random.default_rng(4)
    a, b = rng.normal(size=shapes[0]), rng.normal(size=shapes[1])
    for x, y in ((a, b), (a.astype(np.float32), b.astype(np.float32))):
        ours = R.cross(x, y)
        assert ours.dtype == x.dtype and np.array_equal(ours, np.cross(x, y))
    assert np.allclose(np.sum(R.cross(a, b) * a, -1), 0, atol=1e-12)  # perpendicular to both
    got = R.cross(jnp.asarray(a, jnp.float32), jnp.asarray(b, jnp.float32))
    assert type(got).__module__.startswith("jax")
    np.testing.assert_allclose(np.asarray(got), np.cross(a, b), rtol=1e-5, atol=1e-5)
