"""4x4 matrices in float64, row-major, acting on column vectors (p' = M @ p), OpenGL conventions.

Clip space is OpenGL's: x, y, z in [-w, w]. The "bias" matrix maps [-1, 1] to [0, 1] as in the
classic shadow-map formulation (Everitt, Rege & Cebenoyan 2001).
"""
from __future__ import annotations

import numpy as np


def normalize(v: np.ndarray) -> np.ndarray:
    """v / |v| along the last axis (float64)."""
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def look_at(eye, target, up) -> np.ndarray:
    """World → view matrix: camera at ``eye`` looking at ``target`` (view looks down −z)."""
    eye = np.asarray(eye, np.float64)
    f = normalize(np.asarray(target, np.float64) - eye)
    s = normalize(np.cross(f, up))
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def look_along(eye, direction) -> np.ndarray:
    """World → view matrix looking from ``eye`` along ``direction``, with an up vector chosen
    not parallel to it (y, or x when the direction is nearly vertical)."""
    d = normalize(direction)
    up = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.99 else np.array([1.0, 0.0, 0.0])
    return look_at(eye, np.asarray(eye, np.float64) + d, up)


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    """OpenGL perspective projection (gluPerspective)."""
    f = 1.0 / np.tan(np.radians(fov_y_deg) / 2.0)
    m = np.zeros((4, 4))
    m[0, 0] = f / aspect
    m[1, 1] = f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2.0 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def perspective_infinite(fov_y_deg: float, aspect: float, near: float, eps: float = 0.0) -> np.ndarray:
    """Perspective projection with the far plane at infinity (Everitt & Kilgard 2002, eq. for
    P_inf): points at infinity (w = 0) land at window depth 1 − ε/2 instead of being clipped."""
    m = perspective(fov_y_deg, aspect, near, 2.0 * near)
    m[2, 2] = eps - 1.0
    m[2, 3] = (eps - 2.0) * near
    return m


def orthographic(left, right, bottom, top, near, far) -> np.ndarray:
    """OpenGL orthographic projection (glOrtho)."""
    m = np.eye(4)
    m[0, 0] = 2.0 / (right - left)
    m[1, 1] = 2.0 / (top - bottom)
    m[2, 2] = -2.0 / (far - near)
    m[0, 3] = -(right + left) / (right - left)
    m[1, 3] = -(top + bottom) / (top - bottom)
    m[2, 3] = -(far + near) / (far - near)
    return m


#: Maps clip-space [-1, 1]^3 (after the perspective divide) to texture/depth space [0, 1]^3.
BIAS = np.array([[0.5, 0, 0, 0.5], [0, 0.5, 0, 0.5], [0, 0, 0.5, 0.5], [0, 0, 0, 1.0]])


def euler_xyz(degrees) -> np.ndarray:
    """3x3 rotation about the fixed x, then y, then z axes (R = Rz @ Ry @ Rx), angles in degrees."""
    ax, ay, az = np.radians(np.asarray(degrees, np.float64))
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def transform_points(m: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Apply the 4x4 ``m`` to (N, 3) points and divide by w; returns (N, 3) float64."""
    pts = np.asarray(pts, np.float64)
    h = pts @ m[:3, :3].T + m[:3, 3]
    w = pts @ m[3, :3] + m[3, 3]
    return h / w[:, None]
