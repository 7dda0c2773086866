"""Tests for emotive.transforms.rotations and its NumPy wrappers (np_rotations)."""

from __future__ import annotations

import math
import warnings
from typing import ClassVar

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive.transforms import np_rotations as npr
from emotive.transforms import rotations as r

PROPS = settings(max_examples=40, deadline=None)
DT = torch.float64

finite = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
vec4 = st.tuples(finite, finite, finite, finite).filter(
    lambda v: sum(x * x for x in v) > 1e-2
)
angle = st.floats(-math.pi, math.pi, allow_nan=False)
angles3 = st.tuples(angle, angle, angle)
axis_angles = st.tuples(
    st.floats(-3.0, 3.0, allow_nan=False),
    st.floats(-3.0, 3.0, allow_nan=False),
    st.floats(-3.0, 3.0, allow_nan=False),
).filter(lambda v: sum(x * x for x in v) < 3.1**2)


def unit(v) -> torch.Tensor:
    return r.quaternion_normalize(torch.tensor(v, dtype=DT))


def random_quats(shape: tuple[int, ...], seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return r.quaternion_normalize(torch.randn(*shape, 4, generator=g, dtype=DT))


def same_rotation(a: torch.Tensor, b: torch.Tensor, atol: float = 1e-9) -> bool:
    """Quaternions equal up to sign (q and -q are one rotation)."""
    return bool(((a * b).sum(-1).abs() - 1.0).abs().max() < atol)


def rodrigues(axis: torch.Tensor, theta: float) -> torch.Tensor:
    """Reference rotation matrix about a unit axis, written independently of the kernels."""
    x, y, z = axis.tolist()
    k = torch.tensor([[0, -z, y], [z, 0, -x], [-y, x, 0]], dtype=DT)
    return torch.eye(3, dtype=DT) + math.sin(theta) * k + (1 - math.cos(theta)) * k @ k


class TestQuaternionNormalize:
    def test_smoke(self):
        q = r.quaternion_normalize(torch.tensor([2.0, 0.0, 0.0, 0.0], dtype=DT))
        assert torch.allclose(q, torch.tensor([1.0, 0, 0, 0], dtype=DT))

    def test_batch_unit_norm(self):
        q = r.quaternion_normalize(torch.randn(3, 5, 4, dtype=DT))
        assert q.shape == (3, 5, 4)
        assert torch.allclose(q.norm(dim=-1), torch.ones(3, 5, dtype=DT))

    def test_zero_becomes_identity(self):
        q = r.quaternion_normalize(torch.zeros(2, 4, dtype=DT))
        assert torch.equal(q, r.quaternion_identity((2,), dtype=DT))

    def test_bad_shape(self):
        with pytest.raises(ValueError, match=r"\(\.\.\., 4\)"):
            r.quaternion_normalize(torch.zeros(3))


class TestQuaternionIdentity:
    def test_shape_dtype(self):
        q = r.quaternion_identity((2, 3), dtype=DT)
        assert q.shape == (2, 3, 4) and q.dtype == DT
        assert torch.equal(q[..., 0], torch.ones(2, 3, dtype=DT))


class TestQuaternionMultiply:
    @PROPS
    @given(vec4, vec4)
    def test_matches_matrix_product(self, a, b):
        qa, qb = unit(a), unit(b)
        m = r.quaternion_to_matrix(r.quaternion_multiply(qa, qb))
        ref = r.quaternion_to_matrix(qa) @ r.quaternion_to_matrix(qb)
        assert torch.allclose(m, ref, atol=1e-12)

    def test_identity(self):
        q = random_quats((7,))
        assert torch.allclose(r.quaternion_multiply(r.quaternion_identity((7,), dtype=DT), q), q)
        assert torch.allclose(r.quaternion_multiply(q, r.quaternion_identity((7,), dtype=DT)), q)

    def test_batch_equals_single_and_broadcasts(self):
        a, b = random_quats((4, 3), 1), random_quats((3,), 2)
        out = r.quaternion_multiply(a, b)
        assert out.shape == (4, 3, 4)
        for i in range(4):
            for j in range(3):
                assert torch.allclose(out[i, j], r.quaternion_multiply(a[i, j], b[j]))

    def test_gradient(self):
        a = random_quats((2,), 3).requires_grad_()
        b = random_quats((2,), 4).requires_grad_()
        assert torch.autograd.gradcheck(r.quaternion_multiply, (a, b))


class TestQuaternionConjugateInvert:
    def test_inverse_gives_identity(self):
        q = random_quats((5,)) * 3.0
        prod = r.quaternion_multiply(q, r.quaternion_invert(q))
        assert torch.allclose(prod, r.quaternion_identity((5,), dtype=DT), atol=1e-12)

    def test_conjugate_of_unit_is_inverse(self):
        q = random_quats((5,))
        assert torch.allclose(r.quaternion_conjugate(q), r.quaternion_invert(q))


class TestQuaternionApply:
    @PROPS
    @given(vec4, st.tuples(finite, finite, finite))
    def test_matches_matrix_multiply(self, q, v):
        q, v = unit(q), torch.tensor(v, dtype=DT)
        assert torch.allclose(r.quaternion_apply(q, v), r.quaternion_to_matrix(q) @ v, atol=1e-12)

    def test_known_rotation(self):
        qz = r.axis_angle_to_quaternion(torch.tensor([0.0, 0.0, math.pi / 2], dtype=DT))
        out = r.quaternion_apply(qz, torch.tensor([1.0, 0.0, 0.0], dtype=DT))
        assert torch.allclose(out, torch.tensor([0.0, 1.0, 0.0], dtype=DT), atol=1e-12)

    def test_broadcast(self):
        q, v = random_quats((4, 1)), torch.randn(1, 6, 3, dtype=DT)
        out = r.quaternion_apply(q, v)
        assert out.shape == (4, 6, 3)
        assert torch.allclose(out[2, 5], r.quaternion_apply(q[2, 0], v[0, 5]))

    def test_gradient(self):
        q = random_quats((3,)).requires_grad_()
        v = torch.randn(3, 3, dtype=DT, requires_grad=True)
        assert torch.autograd.gradcheck(r.quaternion_apply, (q, v))


class TestQuaternionContinuity:
    def test_flips_fixed_and_rotations_kept(self):
        g = torch.Generator().manual_seed(0)
        smooth = r.quaternion_slerp(
            random_quats((1, 3), 5), random_quats((1, 3), 6),
            torch.linspace(0, 1, 50, dtype=DT)[:, None],
        )
        signs = torch.where(torch.rand(50, 3, 1, generator=g) < 0.5, -1.0, 1.0).to(DT)
        signs[0] = 1.0
        out = r.quaternion_continuity(smooth * signs, dim=0)
        assert ((out[1:] * out[:-1]).sum(-1) >= 0).all()
        assert torch.allclose(out, smooth, atol=1e-12)

    def test_other_dim(self):
        q = random_quats((3, 20))
        out = r.quaternion_continuity(q, dim=1)
        assert ((out[:, 1:] * out[:, :-1]).sum(-1) >= 0).all()
        assert same_rotation(out, q)

    def test_short_sequences_and_bad_dim(self):
        q = random_quats((1, 2))
        assert torch.equal(r.quaternion_continuity(q, dim=0), q)
        with pytest.raises(ValueError, match="leading dimension"):
            r.quaternion_continuity(q, dim=-1)


class TestQuaternionSlerp:
    @PROPS
    @given(vec4, vec4)
    def test_endpoints_and_midpoint(self, a, b):
        qa, qb = unit(a), unit(b)
        assert same_rotation(r.quaternion_slerp(qa, qb, 0.0), qa)
        assert same_rotation(r.quaternion_slerp(qa, qb, 1.0), qb)
        mid = r.quaternion_slerp(qa, qb, 0.5)
        # The midpoint is half the relative rotation away from both ends.
        rel = r.quaternion_multiply(r.quaternion_conjugate(qa), qb)
        half = r.quaternion_to_axis_angle(rel) * 0.5
        expected = r.quaternion_multiply(qa, r.axis_angle_to_quaternion(half))
        assert same_rotation(mid, expected, atol=1e-9)

    def test_shorter_arc(self):
        qa, qb = random_quats((2,), 7).unbind(0)
        assert same_rotation(r.quaternion_slerp(qa, qb, 0.3), r.quaternion_slerp(qa, -qb, 0.3))

    def test_constant_angular_speed(self):
        qa = r.quaternion_identity(dtype=DT)
        qb = r.axis_angle_to_quaternion(torch.tensor([0.0, 2.0, 0.0], dtype=DT))
        t = torch.linspace(0, 1, 5, dtype=DT)
        out = r.quaternion_slerp(qa, qb, t)
        assert torch.allclose(r.quaternion_to_axis_angle(out)[:, 1], 2.0 * t, atol=1e-12)

    def test_batch_weights(self):
        a, b = random_quats((6, 4), 1), random_quats((6, 4), 2)
        t = torch.rand(6, 4, dtype=DT)
        out = r.quaternion_slerp(a, b, t)
        assert out.shape == (6, 4, 4)
        assert torch.allclose(out[3, 2], r.quaternion_slerp(a[3, 2], b[3, 2], t[3, 2]))

    def test_gradient_finite_including_equal_inputs(self):
        a = random_quats((4,), 1).requires_grad_()
        b = torch.cat((a.detach()[:2], random_quats((2,), 2)))
        r.quaternion_slerp(a, b, 0.3).sum().backward()
        assert torch.isfinite(a.grad).all()
        b = random_quats((4,), 2)
        assert torch.autograd.gradcheck(lambda x: r.quaternion_slerp(x, b, 0.3), (a,))


class TestQuaternionMatrix:
    @PROPS
    @given(vec4)
    def test_round_trip(self, q):
        q = unit(q)
        m = r.quaternion_to_matrix(q)
        assert torch.allclose(m @ m.T, torch.eye(3, dtype=DT), atol=1e-12)
        assert torch.isclose(torch.linalg.det(m), torch.tensor(1.0, dtype=DT))
        back = r.matrix_to_quaternion(m)
        assert back[0] >= 0
        assert same_rotation(back, q, atol=1e-12)

    @pytest.mark.parametrize("axis", [(1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0), (0.6, 0, 0.8)])
    @pytest.mark.parametrize("theta", [0.3, math.pi / 2, math.pi - 1e-9, math.pi])
    def test_matches_rodrigues_including_half_turns(self, axis, theta):
        axis_t = torch.tensor(axis, dtype=DT)
        q = r.axis_angle_to_quaternion(axis_t * theta)
        ref = rodrigues(axis_t, theta)
        assert torch.allclose(r.quaternion_to_matrix(q), ref, atol=1e-12)
        assert same_rotation(r.matrix_to_quaternion(ref), q, atol=1e-12)

    def test_batch_and_bad_shape(self):
        q = random_quats((2, 3))
        assert r.quaternion_to_matrix(q).shape == (2, 3, 3, 3)
        assert r.matrix_to_quaternion(r.quaternion_to_matrix(q)).shape == (2, 3, 4)
        with pytest.raises(ValueError, match=r"\(\.\.\., 3, 3\)"):
            r.matrix_to_quaternion(torch.eye(4))

    def test_gradient(self):
        q = random_quats((3,)).requires_grad_()
        assert torch.autograd.gradcheck(r.quaternion_to_matrix, (q,))
        m = r.quaternion_to_matrix(random_quats((3,), 1)).requires_grad_()
        assert torch.autograd.gradcheck(r.matrix_to_quaternion, (m,))


class TestEuler:
    @pytest.mark.parametrize("order", r.EULER_ORDERS)
    @PROPS
    @given(q=vec4)
    def test_round_trip_quaternion(self, order, q):
        q = unit(q)
        e = r.quaternion_to_euler(q, order)
        assert -math.pi / 2 - 1e-12 <= e[1] <= math.pi / 2 + 1e-12
        assert same_rotation(r.euler_to_quaternion(e, order), q, atol=1e-9)

    @pytest.mark.parametrize("order", r.EULER_ORDERS)
    @PROPS
    @given(a=angles3)
    def test_round_trip_angles(self, order, a):
        a = torch.tensor(a, dtype=DT)
        m = r.euler_to_matrix(a, order)
        assert torch.allclose(r.euler_to_matrix(r.matrix_to_euler(m, order), order), m, atol=1e-9)
        q = r.euler_to_quaternion(a, order)
        assert torch.allclose(r.quaternion_to_matrix(q), m, atol=1e-12)

    @pytest.mark.parametrize("order", r.EULER_ORDERS)
    @pytest.mark.parametrize("middle", [math.pi / 2, -math.pi / 2])
    def test_gimbal_lock(self, order, middle):
        a = torch.tensor([0.7, middle, -0.4], dtype=DT)
        m = r.euler_to_matrix(a, order)
        e = r.matrix_to_euler(m, order)
        assert e[2] == 0.0
        assert torch.allclose(r.euler_to_matrix(e, order), m, atol=1e-9)

    @pytest.mark.parametrize("order", r.EULER_ORDERS)
    @pytest.mark.parametrize("middle", [math.radians(-89.9983), math.pi / 2 - 1e-7])
    def test_near_gimbal_lock_keeps_angles(self, order, middle):
        # A Bandai clip holds Hips angles (-84.7481, -89.9983, -176.47) degrees.
        a = torch.tensor([math.radians(-84.7481), middle, math.radians(-176.47)], dtype=DT)
        e = r.matrix_to_euler(r.euler_to_matrix(a, order), order)
        assert torch.allclose(e, a, atol=1e-8)

    @pytest.mark.parametrize("order", r.EULER_ORDERS)
    def test_intrinsic_convention(self, order):
        a = torch.tensor([0.3, -0.5, 1.1], dtype=DT)
        axes = {"X": (1.0, 0, 0), "Y": (0, 1.0, 0), "Z": (0, 0, 1.0)}
        ref = torch.eye(3, dtype=DT)
        for axis, theta in zip(order, a.tolist(), strict=True):
            ref = ref @ rodrigues(torch.tensor(axes[axis], dtype=DT), theta)
        assert torch.allclose(r.euler_to_matrix(a, order), ref, atol=1e-12)

    def test_lower_case_order_batch_and_errors(self):
        a = torch.rand(4, 2, 3, dtype=DT)
        assert torch.allclose(r.euler_to_matrix(a, "zxy"), r.euler_to_matrix(a, "ZXY"))
        assert r.euler_to_quaternion(a, "ZXY").shape == (4, 2, 4)
        with pytest.raises(ValueError, match="Euler order"):
            r.euler_to_matrix(a, "XXY")
        with pytest.raises(ValueError):
            r.matrix_to_euler(torch.eye(4), "XYZ")

    def test_gradient_away_from_lock(self):
        a = torch.tensor([[0.3, 0.2, -0.5], [1.0, -0.7, 0.4]], dtype=DT, requires_grad=True)
        assert torch.autograd.gradcheck(lambda x: r.euler_to_quaternion(x, "ZXY"), (a,))
        m = r.euler_to_matrix(a.detach(), "YZX").requires_grad_()
        assert torch.autograd.gradcheck(lambda x: r.matrix_to_euler(x, "YZX"), (m,))


class TestAxisAngle:
    @PROPS
    @given(axis_angles)
    def test_round_trip(self, v):
        v = torch.tensor(v, dtype=DT)
        q = r.axis_angle_to_quaternion(v)
        assert torch.isclose(q.norm(), torch.tensor(1.0, dtype=DT))
        assert torch.allclose(r.quaternion_to_axis_angle(q), v, atol=1e-9)

    @PROPS
    @given(vec4)
    def test_log_then_exp(self, q):
        q = unit(q)
        v = r.quaternion_to_axis_angle(q)
        assert v.norm() <= math.pi + 1e-9
        assert same_rotation(r.axis_angle_to_quaternion(v), q, atol=1e-9)

    def test_tiny_angles(self):
        v = torch.tensor([[1e-9, 0, 0], [0, 3e-5, 0], [0, 0, 0]], dtype=DT)
        assert torch.allclose(r.quaternion_to_axis_angle(r.axis_angle_to_quaternion(v)), v)

    def test_gradient_at_identity_and_elsewhere(self):
        zero = torch.zeros(2, 3, dtype=DT, requires_grad=True)
        r.axis_angle_to_quaternion(zero).sum().backward()
        assert torch.isfinite(zero.grad).all()
        ident = r.quaternion_identity((2,), dtype=DT).requires_grad_()
        r.quaternion_to_axis_angle(ident).sum().backward()
        assert torch.isfinite(ident.grad).all()
        v = torch.tensor([[0.3, -0.2, 0.9], [1e-5, 0.0, 0.0]], dtype=DT, requires_grad=True)
        assert torch.autograd.gradcheck(r.axis_angle_to_quaternion, (v,))
        q = random_quats((3,)).requires_grad_()
        assert torch.autograd.gradcheck(r.quaternion_to_axis_angle, (q,))


class TestRotation6D:
    @PROPS
    @given(vec4)
    def test_round_trip(self, q):
        q = unit(q)
        d6 = r.quaternion_to_rotation_6d(q)
        assert d6.shape == (6,)
        assert same_rotation(r.rotation_6d_to_quaternion(d6), q, atol=1e-12)
        m = r.quaternion_to_matrix(q)
        assert torch.allclose(r.rotation_6d_to_matrix(r.matrix_to_rotation_6d(m)), m, atol=1e-12)

    def test_unnormalized_input_gives_rotation(self):
        m = r.rotation_6d_to_matrix(torch.randn(5, 6, dtype=DT) * 3)
        eye = torch.eye(3, dtype=DT).expand(5, 3, 3)
        assert torch.allclose(m @ m.transpose(-1, -2), eye, atol=1e-12)
        assert torch.allclose(torch.linalg.det(m), torch.ones(5, dtype=DT))

    def test_gradient(self):
        d6 = torch.randn(3, 6, dtype=DT, requires_grad=True)
        assert torch.autograd.gradcheck(r.rotation_6d_to_matrix, (d6,))


class TestQuaternionBetween:
    def test_maps_u_onto_v(self):
        u, v = torch.randn(10, 3, dtype=DT), torch.randn(10, 3, dtype=DT)
        q = r.quaternion_between(u, v)
        out = r.quaternion_apply(q, torch.nn.functional.normalize(u, dim=-1))
        assert torch.allclose(out, torch.nn.functional.normalize(v, dim=-1), atol=1e-12)

    def test_parallel_and_opposite(self):
        u = torch.tensor([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [1, 2, 3.0]], dtype=DT)
        assert same_rotation(r.quaternion_between(u, u), r.quaternion_identity((4,), dtype=DT))
        q = r.quaternion_between(u, -u)
        assert torch.allclose(r.quaternion_apply(q, u), -u, atol=1e-12)


class TestYawQuaternion:
    def test_turns_z_to_heading(self):
        a = torch.linspace(-3, 3, 7, dtype=DT)
        out = r.quaternion_apply(r.yaw_quaternion(a), torch.tensor([0.0, 0.0, 1.0], dtype=DT))
        ref = torch.stack((a.sin(), torch.zeros_like(a), a.cos()), -1)
        assert torch.allclose(out, ref, atol=1e-12)


class TestNumpyWrappers:
    CASES: ClassVar = [
        ("quaternion_normalize", lambda g: (g.normal(size=(5, 4)),)),
        ("quaternion_multiply", lambda g: (g.normal(size=(5, 4)), g.normal(size=(5, 4)))),
        ("quaternion_conjugate", lambda g: (g.normal(size=(5, 4)),)),
        ("quaternion_invert", lambda g: (g.normal(size=(5, 4)),)),
        ("quaternion_apply", lambda g: (g.normal(size=(5, 4)), g.normal(size=(5, 3)))),
        ("quaternion_to_matrix", lambda g: (g.normal(size=(5, 4)),)),
        ("matrix_to_rotation_6d", lambda g: (g.normal(size=(5, 3, 3)),)),
        ("rotation_6d_to_matrix", lambda g: (g.normal(size=(5, 6)),)),
        ("rotation_6d_to_quaternion", lambda g: (g.normal(size=(5, 6)),)),
        ("axis_angle_to_quaternion", lambda g: (g.normal(size=(5, 3)),)),
        ("quaternion_to_axis_angle", lambda g: (g.normal(size=(5, 4)),)),
        ("quaternion_between", lambda g: (g.normal(size=(5, 3)), g.normal(size=(5, 3)))),
        ("yaw_quaternion", lambda g: (g.normal(size=(5,)),)),
    ]

    @pytest.mark.parametrize(("name", "make"), CASES, ids=[c[0] for c in CASES])
    def test_equal_to_torch(self, name, make):
        args = make(np.random.default_rng(0))
        out = getattr(npr, name)(*args)
        ref = getattr(r, name)(*(torch.from_numpy(a) for a in args))
        assert isinstance(out, np.ndarray) and out.dtype == np.float64
        np.testing.assert_allclose(out, ref.numpy(), atol=1e-15)

    @pytest.mark.parametrize("order", r.EULER_ORDERS)
    def test_euler_wrappers(self, order):
        a = np.random.default_rng(1).uniform(-1, 1, size=(4, 3))
        np.testing.assert_allclose(
            npr.euler_to_quaternion(a, order),
            r.euler_to_quaternion(torch.from_numpy(a), order).numpy(),
        )
        q = npr.euler_to_quaternion(a, order)
        np.testing.assert_allclose(npr.quaternion_to_euler(q, order), a, atol=1e-12)
        m = npr.euler_to_matrix(a, order)
        np.testing.assert_allclose(npr.matrix_to_euler(m, order), a, atol=1e-12)
        np.testing.assert_allclose(npr.matrix_to_quaternion(m), q * np.sign(q[:, :1]), atol=1e-12)

    def test_read_only_input(self):
        q = np.array([[1.0, 0.0, 0.0, 0.0]])
        q.setflags(write=False)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            np.testing.assert_array_equal(npr.quaternion_to_matrix(q)[0], np.eye(3))

    def test_slerp_continuity_and_float32(self):
        g = np.random.default_rng(2)
        a = npr.quaternion_normalize(g.normal(size=(6, 4)))
        b = npr.quaternion_normalize(g.normal(size=(6, 4)))
        t = g.uniform(size=6)
        ref = r.quaternion_slerp(torch.from_numpy(a), torch.from_numpy(b), torch.from_numpy(t))
        np.testing.assert_allclose(npr.quaternion_slerp(a, b, t), ref.numpy())
        np.testing.assert_allclose(
            npr.quaternion_continuity(a, dim=0),
            r.quaternion_continuity(torch.from_numpy(a)).numpy(),
        )
        assert npr.quaternion_to_matrix(a.astype(np.float32)).dtype == np.float32


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 10_000), spread=st.floats(0.0, 0.3), flips=st.integers(0, 5))
def test_quaternion_mean_recovers_the_centre_whatever_the_signs(seed, spread, flips):
    rng = np.random.default_rng(seed)
    centre = npr.quaternion_normalize(rng.normal(size=4))
    # Rotations scattered symmetrically about the centre: +-delta pairs.
    delta = npr.axis_angle_to_quaternion(rng.normal(size=(6, 3)) * spread)
    q = np.concatenate([npr.quaternion_multiply(centre[None], delta),
                        npr.quaternion_multiply(centre[None], npr.quaternion_conjugate(delta))])
    q[:flips] *= -1.0  # the sign of a quaternion does not change its rotation
    mean = npr.quaternion_mean(q)
    assert mean[0] >= 0 and abs(np.linalg.norm(mean) - 1) < 1e-9
    assert abs(abs(float(mean @ centre)) - 1) < 1e-6


def test_quaternion_mean_along_an_axis():
    q = np.zeros((3, 5, 4))
    q[..., 0] = 1.0
    q[1, :, 0] = -1.0
    np.testing.assert_allclose(npr.quaternion_mean(q, axis=0), np.tile([1.0, 0, 0, 0], (5, 1)))
    assert npr.quaternion_mean(q, axis=1).shape == (3, 4)
    q[0, 2, 1] = np.nan
    mean = npr.quaternion_mean(q, axis=0)
    assert np.isnan(mean[2]).all() and np.isfinite(np.delete(mean, 2, 0)).all()


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 6))
def test_batch_last_products_equal_the_components_last_ones(seed, batch):
    g = torch.Generator().manual_seed(seed)
    a = torch.randn(3, batch, 4, generator=g, dtype=torch.float64)
    b = torch.randn(1, batch, 4, generator=g, dtype=torch.float64)
    v = torch.randn(3, batch, 3, generator=g, dtype=torch.float64)
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    hamilton = torch.stack((aw * bw - ax * bx - ay * by - az * bz,
                            aw * bx + ax * bw + ay * bz - az * by,
                            aw * by - ax * bz + ay * bw + az * bx,
                            aw * bz + ax * by - ay * bx + az * bw), -1)
    torch.testing.assert_close(r.quaternion_multiply(a, b), hamilton)
    last = r.quaternion_multiply(a.transpose(-1, -2), b.transpose(-1, -2), -2)
    torch.testing.assert_close(last.transpose(-1, -2), hamilton)
    u = a[..., 1:]
    torch.testing.assert_close(r.cross_product(u, v), torch.linalg.cross(u, v))
    torch.testing.assert_close(
        r.cross_product(u.transpose(-1, -2), v.transpose(-1, -2), -2).transpose(-1, -2),
        torch.linalg.cross(u, v))
    q = r.quaternion_normalize(a)
    torch.testing.assert_close(r.quaternion_rotate(q, v), r.quaternion_apply(q, v))
    torch.testing.assert_close(
        r.quaternion_rotate(q.transpose(-1, -2), v.transpose(-1, -2), -2).transpose(-1, -2),
        r.quaternion_apply(q, v))


def test_quaternion_multiply_takes_the_components_last_or_second_last_only():
    q = torch.tensor([[1.0, 0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="dim must be -1 or -2"):
        r.quaternion_multiply(q, q, 0)
    with pytest.raises(ValueError, match=r"a must have shape \(\.\.\., 4, B\)"):
        r.quaternion_multiply(q, q.T, -2)
