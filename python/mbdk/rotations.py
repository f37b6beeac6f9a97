"""Rotations in three dimensions, computed by the kernel (kernel/src/spatial/mbdk_rotations.f90,
whose header states the conventions): rotation matrices from Euler or Cardan angles, unit
quaternions (scalar first) and an Euler axis with its angle; the maps between angle rates,
quaternion rates and angular velocity in the space and the body frame.

R maps body components to space components; an angle sequence "313" is R_z(a1) R_x(a2) R_z(a3)
(rotations about moving axes), "123" is R_x R_y R_z; any of the twelve sequences of three axes
with no axis repeated twice in a row may be given. omega is the space-frame angular velocity
(skew(omega) = R' R^T), Omega the body-frame one (R^T omega).

Bad input raises InvalidInputError naming the argument and value; angle rates at a gimbal lock
(3-1-3 at theta = 0 or pi, 1-2-3 at beta = +-90 deg) raise GimbalLockError.
"""
from __future__ import annotations

import numpy as np

from . import _kernel
from .codes import FRAMES, ROTATION_PARAMETRISATIONS
from .errors import InvalidInputError, SingularMatrixError, Status

SEQUENCES = ("121", "123", "131", "132", "212", "213", "231", "232", "312", "313", "321", "323")


def dot_fixed(a, b) -> float:
    """a . b summed left to right in Python floats. A scene's numbers (body-frame points and
    axes, unit vectors, initial states) go through this and not numpy's dot or matmul, which
    call BLAS: its kernel, chosen for the CPU, orders a sum its own way, and the last bits of a
    scene, and of every run from it, would change with the machine."""
    s = 0.0
    for x, y in zip(a, b):
        s += float(x) * float(y)
    return s


def norm_fixed(a) -> float:
    """|a| by dot_fixed (not np.linalg.norm, which calls BLAS)."""
    return float(np.sqrt(dot_fixed(a, a)))


def matvec_fixed(m, x) -> np.ndarray:
    """m x row by row by dot_fixed (not m @ x, which calls BLAS); m.T for R^T x."""
    return np.array([dot_fixed(row, x) for row in np.asarray(m)])


class GimbalLockError(SingularMatrixError):
    """The angle rates of an angular velocity are undefined: the sequence's middle angle is at
    its singular value, where two of the three rotation axes coincide."""


def _seq(sequence) -> np.ndarray:
    s = str(sequence)
    if s not in SEQUENCES:
        raise InvalidInputError(f"sequence = {sequence!r}: not an angle sequence; known: "
                                f"{', '.join(SEQUENCES)} (313 Euler, 123 Cardan)")
    return np.array([int(c) for c in s], dtype=np.int32)


def _vec(name: str, x, n: int) -> np.ndarray:
    v = np.asarray(x, dtype=float).reshape(-1)
    if v.size != n:
        raise InvalidInputError(f"{name} = {x!r}: needs {n} numbers, got {v.size}")
    if not np.all(np.isfinite(v)):
        raise InvalidInputError(f"{name} = {x!r}: not finite")
    return v


def _unit(q) -> np.ndarray:
    q = _vec("quaternion", q, 4)
    if abs(np.linalg.norm(q) - 1.0) > 1e-8:
        raise InvalidInputError(f"quaternion = {q.tolist()}: its norm is {np.linalg.norm(q):.12g},"
                                " not 1 (give a unit quaternion, scalar first; mbdk normalises "
                                "nothing silently)")
    return q


def _frame(frame: str) -> int:
    if frame not in FRAMES:
        raise InvalidInputError(f"frame = {frame!r}: 'space' or 'body'")
    return FRAMES[frame]


def from_angles(angles, sequence="313") -> np.ndarray:
    """R = R_s1(a1) R_s2(a2) R_s3(a3) (radians)."""
    r, st = _kernel.rotation_matrix(ROTATION_PARAMETRISATIONS["angles"],
                                    np.r_[_vec("angles", angles, 3), 0.0], _seq(sequence))
    return r


def from_quaternion(q) -> np.ndarray:
    """The rotation matrix of a unit quaternion (s, x, y, z)."""
    r, st = _kernel.rotation_matrix(ROTATION_PARAMETRISATIONS["quaternion"],
                                    _unit(q), np.zeros(3, np.int32))
    return r


def from_axis_angle(axis, angle: float) -> np.ndarray:
    """Rodrigues: the rotation by angle (radians) about axis (any length but zero)."""
    a = _vec("axis", axis, 3)
    if not np.linalg.norm(a) > 0:
        raise InvalidInputError(f"axis = {axis!r} has zero length: no direction to rotate about")
    r, st = _kernel.rotation_matrix(ROTATION_PARAMETRISATIONS["axis_angle"],
                                    np.r_[a, _vec("angle", angle, 1)],
                                    np.zeros(3, np.int32))
    return r


def to_quaternion(r) -> np.ndarray:
    """The unit quaternion of a rotation matrix, scalar part >= 0."""
    q, _axis, _angle, st = _kernel.rotation_from_matrix(_rotation(r))
    return q


def to_axis_angle(r) -> tuple[np.ndarray, float]:
    """The unit axis and the angle in [0, pi] of a rotation matrix."""
    _q, axis, angle, st = _kernel.rotation_from_matrix(_rotation(r))
    return axis, float(angle)


def _rotation(r) -> np.ndarray:
    m = np.asarray(r, dtype=float)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise InvalidInputError(f"R: needs a finite 3 x 3 matrix, got shape {m.shape}")
    e = np.abs(m.T @ m - np.eye(3)).max()
    if e > 1e-8 or np.linalg.det(m) <= 0:
        raise InvalidInputError(f"R is not a rotation: |R^T R - I| = {e:.3g}, det R = "
                                f"{np.linalg.det(m):.6g} (needs R^T R = I and det R = +1)")
    return np.asfortranarray(m)


def angle_rate_maps(angles, sequence="313") -> tuple[np.ndarray, np.ndarray]:
    """(G_s, G_b): omega = G_s a', Omega = G_b a'."""
    gs, gb, _det, st = _kernel.angle_rate_maps(_seq(sequence), _vec("angles", angles, 3))
    return gs, gb


def angle_rates(angles, omega, sequence="313", frame="space") -> np.ndarray:
    """The angle rates a' of the angular velocity omega (given in frame 'space' or 'body')."""
    seq = _seq(sequence)
    a = _vec("angles", angles, 3)
    ad, st = _kernel.angle_rates(seq, a, _vec("omega", omega, 3), _frame(frame))
    if st == Status.ERR_SINGULAR_MATRIX:
        raise GimbalLockError(
            f"sequence {sequence}: the middle angle {a[1]!r} rad is at a gimbal lock (its "
            f"{'sine' if seq[0] == seq[2] else 'cosine'} vanishes): two rotation axes coincide "
            "and the angle rates of this angular velocity are undefined. Use quaternions, or "
            "the other sequence (313 locks at 0 and pi, 123 at +-pi/2)",
            status=Status.ERR_SINGULAR_MATRIX)
    return ad


def quaternion_product(p, q) -> np.ndarray:
    """p q (scalar first)."""
    pq, _qd, _w, _st = _kernel.quaternion_ops(_vec("p", p, 4), _vec("q", q, 4), np.zeros(3),
                                              FRAMES["space"])
    return pq


def quaternion_rates(q, omega, frame="space") -> np.ndarray:
    """q' = (1/2) (0, omega) q (space) or (1/2) q (0, Omega) (body)."""
    _pq, qd, _w, _st = _kernel.quaternion_ops(np.zeros(4), _unit(q), _vec("omega", omega, 3),
                                              _frame(frame))
    return qd


def quaternion_omega(q, qd, frame="space") -> np.ndarray:
    """The angular velocity of the quaternion rates qd: 2 vec(q' q*) (space) or 2 vec(q* q')
    (body)."""
    body = _frame(frame)
    w, st = _kernel.quaternion_omega(_unit(q), _vec("qd", qd, 4), body)
    return w


def quaternion_rotate(q, x) -> np.ndarray:
    """R x by the sandwich product q (0, x) q*."""
    y, st = _kernel.quaternion_rotate(_unit(q), _vec("x", x, 3))
    return y
