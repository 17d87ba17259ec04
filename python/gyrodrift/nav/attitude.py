"""Attitude helpers: quaternions [w, x, y, z] (Hamilton), DCMs and Euler angles.

q_nb rotates body vectors into the navigation frame (v_n = q v_b q*). Euler angles follow the
PSINS convention att = [pitch, roll, yaw] with C_b^n = Rz(yaw) Rx(pitch) Ry(roll) and yaw
positive counter-clockwise from North; `heading_rad` (clockwise from North) is -yaw.
Reference for include/gyrodrift/nav/attitude.hpp.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "dcm2euler",
    "dcm2q",
    "euler2dcm",
    "misalignment",
    "q2dcm",
    "qmul",
    "qnormalize",
    "rv2q",
    "skew",
    "wrap_pi",
]


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix [v x]: skew(v) @ w = v x w.

    Examples
    --------
    >>> skew(np.array([1.0, 2.0, 3.0])) @ np.array([1.0, 0.0, 0.0])  # v x e1
    array([ 0.,  3., -2.])
    """
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Quaternion product p * q (scalar first).

    Examples
    --------
    >>> qmul(np.array([1.0, 0, 0, 0]), np.array([0.0, 1, 0, 0]))
    array([0., 1., 0., 0.])
    """
    pw, px, py, pz = p
    qw, qx, qy, qz = q
    return np.array([
        pw * qw - px * qx - py * qy - pz * qz,
        pw * qx + px * qw + py * qz - pz * qy,
        pw * qy - px * qz + py * qw + pz * qx,
        pw * qz + px * qy - py * qx + pz * qw,
    ])


def rv2q(rv: np.ndarray) -> np.ndarray:
    """Rotation vector to quaternion; Taylor series below 1e-4 rad keeps full precision.

    Examples
    --------
    >>> q = rv2q(np.array([0.0, 0.0, np.pi / 2]))
    >>> np.round(q, 6).tolist()
    [0.707107, 0.0, 0.0, 0.707107]
    """
    a2 = float(rv @ rv)
    if a2 < 1e-8:
        c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0
        s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
    else:
        a = np.sqrt(a2)
        c = np.cos(a / 2.0)
        s = np.sin(a / 2.0) / a
    return np.array([c, s * rv[0], s * rv[1], s * rv[2]])


def qnormalize(q: np.ndarray) -> np.ndarray:
    """The quaternion scaled to unit norm.

    Examples
    --------
    >>> qnormalize(np.array([2.0, 0.0, 0.0, 0.0]))
    array([1., 0., 0., 0.])
    """
    return q / np.sqrt(q @ q)


def q2dcm(q: np.ndarray) -> np.ndarray:
    """

    Examples
    --------
    >>> bool(np.allclose(q2dcm(np.array([1.0, 0, 0, 0])), np.eye(3)))
    True
    """
    w, x, y, z = q
    return np.array([
        [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
    ])


def dcm2q(c: np.ndarray) -> np.ndarray:
    """Shepperd's method (largest diagonal pivot), sign fixed to w >= 0.

    Examples
    --------
    >>> q = rv2q(np.array([0.1, -0.2, 0.3]))
    >>> bool(np.allclose(dcm2q(q2dcm(q)), q))
    True
    """
    tr = c[0, 0] + c[1, 1] + c[2, 2]
    cand = [tr, c[0, 0], c[1, 1], c[2, 2]]
    k = int(np.argmax(cand))
    if k == 0:
        w = 0.5 * np.sqrt(1.0 + tr)
        q = np.array([w, (c[2, 1] - c[1, 2]) / (4 * w), (c[0, 2] - c[2, 0]) / (4 * w),
                      (c[1, 0] - c[0, 1]) / (4 * w)])
    elif k == 1:
        x = 0.5 * np.sqrt(1.0 + 2 * c[0, 0] - tr)
        q = np.array([(c[2, 1] - c[1, 2]) / (4 * x), x, (c[0, 1] + c[1, 0]) / (4 * x),
                      (c[0, 2] + c[2, 0]) / (4 * x)])
    elif k == 2:
        y = 0.5 * np.sqrt(1.0 + 2 * c[1, 1] - tr)
        q = np.array([(c[0, 2] - c[2, 0]) / (4 * y), (c[0, 1] + c[1, 0]) / (4 * y), y,
                      (c[1, 2] + c[2, 1]) / (4 * y)])
    else:
        z = 0.5 * np.sqrt(1.0 + 2 * c[2, 2] - tr)
        q = np.array([(c[1, 0] - c[0, 1]) / (4 * z), (c[0, 2] + c[2, 0]) / (4 * z),
                      (c[1, 2] + c[2, 1]) / (4 * z), z])
    return q if q[0] >= 0 else -q


def euler2dcm(att: np.ndarray) -> np.ndarray:
    """C_b^n from [pitch, roll, yaw] (rad), C = Rz(yaw) Rx(pitch) Ry(roll).

    Examples
    --------
    >>> att = np.array([0.01, -0.02, 0.5])
    >>> bool(np.allclose(dcm2euler(euler2dcm(att)), att))
    True
    """
    sp, cp = np.sin(att[0]), np.cos(att[0])
    sr, cr = np.sin(att[1]), np.cos(att[1])
    sy, cy = np.sin(att[2]), np.cos(att[2])
    return np.array([
        [cy * cr - sy * sp * sr, -sy * cp, cy * sr + sy * sp * cr],
        [sy * cr + cy * sp * sr, cy * cp, sy * sr - cy * sp * cr],
        [-cp * sr, sp, cp * cr],
    ])


def dcm2euler(c: np.ndarray) -> np.ndarray:
    """[pitch, roll, yaw] from C_b^n (pitch in [-90, 90] deg).

    Examples
    --------
    >>> np.abs(dcm2euler(np.eye(3))).tolist()
    [0.0, 0.0, 0.0]
    """
    pitch = np.arcsin(np.clip(c[2, 1], -1.0, 1.0))
    roll = np.arctan2(-c[2, 0], c[2, 2])
    yaw = np.arctan2(-c[0, 1], c[1, 1])
    return np.array([pitch, roll, yaw])


def wrap_pi(a: np.ndarray | float) -> np.ndarray | float:
    """The angle `a` (rad) wrapped into [-pi, pi).

    Examples
    --------
    >>> round(float(wrap_pi(3 * np.pi / 2)), 6)
    -1.570796
    """
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def misalignment(c_est: np.ndarray, c_true: np.ndarray) -> np.ndarray:
    """phi with C_est = (I - [phi x]) C_true (small angles): the ENU misalignment, whose Up
    component equals the heading error (clockwise-from-North heading, estimated - true).

    Examples
    --------
    >>> c = euler2dcm(np.array([0.0, 0.0, 0.3]))
    >>> misalignment(c, c).tolist()
    [0.0, 0.0, 0.0]
    """
    d = c_true @ c_est.T  # = I + [phi x]
    return 0.5 * np.array([d[2, 1] - d[1, 2], d[0, 2] - d[2, 0], d[1, 0] - d[0, 1]])
