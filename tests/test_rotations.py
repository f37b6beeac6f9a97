"""The kernel's rotations (kernel/src/spatial/mbdk_rotations.f90, through mbdk.rotations),
each against an independent construction: SciPy's Rotation (a separate implementation of
Euler sequences, quaternions and rotation vectors), central differences of R(t) for angular
velocities (skew(omega) = R' R^T), and the algebraic identities of quaternions."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mbdk import rotations as rot
from mbdk.errors import InvalidInputError

RNG = np.random.default_rng(20)
AXES = "XYZ"


def scipy_seq(seq):
    # upper case: rotations about moving (intrinsic) axes, R = R_s1 R_s2 R_s3
    return "".join(AXES[int(c) - 1] for c in seq)


def unskew(w):
    return 0.5 * np.array([w[2, 1] - w[1, 2], w[0, 2] - w[2, 0], w[1, 0] - w[0, 1]])


@pytest.mark.parametrize("seq", rot.SEQUENCES)
def test_angle_matrices_match_scipy_for_every_sequence(seq):
    for _ in range(20):
        a = RNG.uniform(-np.pi, np.pi, 3)
        ref = Rotation.from_euler(scipy_seq(seq), a).as_matrix()
        assert np.abs(rot.from_angles(a, seq) - ref).max() < 1e-14


def test_313_and_123_are_the_documented_products():
    a = [0.3, -1.1, 2.0]
    rz = lambda t: np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])
    rx = lambda t: np.array([[1, 0, 0], [0, np.cos(t), -np.sin(t)], [0, np.sin(t), np.cos(t)]])
    ry = lambda t: np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    assert np.allclose(rot.from_angles(a, "313"), rz(a[0]) @ rx(a[1]) @ rz(a[2]), atol=1e-15)
    assert np.allclose(rot.from_angles(a, "123"), rx(a[0]) @ ry(a[1]) @ rz(a[2]), atol=1e-15)


def test_quaternion_and_axis_angle_matrices_match_scipy():
    for _ in range(50):
        q = RNG.standard_normal(4)
        q /= np.linalg.norm(q)
        ref = Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_matrix()   # SciPy: scalar last
        assert np.abs(rot.from_quaternion(q) - ref).max() < 1e-14
        e, phi = RNG.standard_normal(3) * 3, RNG.uniform(-7, 7)
        ref = Rotation.from_rotvec(e / np.linalg.norm(e) * phi).as_matrix()
        assert np.abs(rot.from_axis_angle(e, phi) - ref).max() < 1e-14
        x = RNG.standard_normal(3)
        assert np.abs(rot.quaternion_rotate(q, x) - rot.from_quaternion(q) @ x).max() < 1e-14


def test_matrix_to_quaternion_and_axis_angle_round_trip_including_half_turns():
    angles = list(RNG.uniform(0, np.pi, 30)) + [0.0, 1e-12, np.pi - 1e-9, np.pi]
    for phi in angles:
        e = RNG.standard_normal(3)
        e /= np.linalg.norm(e)
        r = rot.from_axis_angle(e, phi)
        q = rot.to_quaternion(r)
        assert q[0] >= 0 and abs(np.linalg.norm(q) - 1) < 1e-15
        assert np.abs(rot.from_quaternion(q) - r).max() < 1e-14
        axis, ang = rot.to_axis_angle(r)
        assert ang == pytest.approx(phi, abs=1e-12)
        if phi > 1e-6:
            # the axis up to its sign at a half turn (e and -e give the same R there)
            assert min(np.abs(axis - e).max(), np.abs(axis + e).max()) < 1e-8


@pytest.mark.parametrize("seq", rot.SEQUENCES)
def test_angle_rate_maps_are_the_derivative_of_r(seq):
    """skew(omega) = R' R^T and skew(Omega) = R^T R', R' by central differences along
    a(t) = a0 + t a'."""
    for _ in range(10):
        a0, ad = RNG.uniform(-1, 1, 3) + [0.0, 0.7, 0.0], RNG.standard_normal(3)
        d = 1e-6
        rp, rm = rot.from_angles(a0 + d * ad, seq), rot.from_angles(a0 - d * ad, seq)
        r = rot.from_angles(a0, seq)
        rdot = (rp - rm) / (2 * d)
        gs, gb = rot.angle_rate_maps(a0, seq)
        assert np.abs(gs @ ad - unskew(rdot @ r.T)).max() < 1e-8
        assert np.abs(gb @ ad - unskew(r.T @ rdot)).max() < 1e-8
        # and the inverse maps give the rates back, from either frame
        assert np.abs(rot.angle_rates(a0, gs @ ad, seq, "space") - ad).max() < 1e-12
        assert np.abs(rot.angle_rates(a0, gb @ ad, seq, "body") - ad).max() < 1e-12


def test_gimbal_lock_is_where_the_middle_angle_makes_two_axes_coincide():
    """3-1-3: det G = -sin(theta), singular at theta = 0 and pi (not at 90 deg, where the
    three axes are orthogonal); 1-2-3: singular at beta = +-90 deg. There the inverse map
    raises GimbalLockError instead of returning rates of 1/0."""
    for th in (0.2, 1.0, np.pi / 2, 2.5):
        gs, _ = rot.angle_rate_maps([0.4, th, -0.3], "313")
        assert abs(np.linalg.det(gs)) == pytest.approx(abs(np.sin(th)), abs=1e-15)
    for seq, lock in (("313", 0.0), ("313", np.pi), ("123", np.pi / 2), ("123", -np.pi / 2)):
        with pytest.raises(rot.GimbalLockError, match="gimbal lock"):
            rot.angle_rates([0.4, lock, -0.3], [0.1, 0.2, 0.3], seq)
    # off the lock the rates grow like 1/sin(theta), as G^-1 says
    ad = rot.angle_rates([0.0, 1e-6, 0.0], [0.0, 1.0, 0.0], "313")
    assert 1e5 < np.abs(ad).max() < 1e7


@pytest.mark.parametrize("frame", ["space", "body"])
def test_quaternion_rates_are_the_derivative_of_the_rotation(frame):
    """q' against the derivative of q(t) = exp(omega t) q0 (space) or q0 exp(Omega t) (body),
    built from SciPy's rotation vectors; and omega back from q'."""
    for _ in range(20):
        q0 = RNG.standard_normal(4)
        q0 /= np.linalg.norm(q0)
        w = RNG.standard_normal(3)

        def q_at(t):
            e = Rotation.from_rotvec(w * t).as_quat()                 # scalar last
            e = np.array([e[3], e[0], e[1], e[2]])
            return rot.quaternion_product(e, q0) if frame == "space" else \
                rot.quaternion_product(q0, e)
        d = 1e-6
        qd_fd = (q_at(d) - q_at(-d)) / (2 * d)
        qd = rot.quaternion_rates(q0, w, frame)
        assert np.abs(qd - qd_fd).max() < 1e-9
        assert abs(np.dot(qd, q0)) < 1e-15        # q' keeps |q| = 1
        assert np.abs(rot.quaternion_omega(q0, qd, frame) - w).max() < 1e-14


def test_quaternion_product_composes_rotations():
    for _ in range(20):
        p, q = RNG.standard_normal(4), RNG.standard_normal(4)
        p /= np.linalg.norm(p)
        q /= np.linalg.norm(q)
        pq = rot.quaternion_product(p, q)
        assert np.abs(rot.from_quaternion(pq) - rot.from_quaternion(p) @ rot.from_quaternion(q)
                      ).max() < 1e-14


def test_bad_input_is_named():
    with pytest.raises(InvalidInputError, match="norm is 1.1"):
        rot.from_quaternion([1.1, 0, 0, 0])
    with pytest.raises(InvalidInputError, match="zero length"):
        rot.from_axis_angle([0, 0, 0], 1.0)
    with pytest.raises(InvalidInputError, match="sequence = '311'"):
        rot.from_angles([0, 0, 0], "311")
    with pytest.raises(InvalidInputError, match="not a rotation"):
        rot.to_quaternion(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(InvalidInputError, match="not finite"):
        rot.from_angles([0, np.nan, 0])
    with pytest.raises(InvalidInputError, match="frame"):
        rot.quaternion_rates([1, 0, 0, 0], [0, 0, 1], "world")
