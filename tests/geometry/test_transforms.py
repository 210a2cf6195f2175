"""4x4 transforms (OpenGL conventions) checked on points whose images are known by hand."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab.geometry import transforms as tf


def apply(m, p):
    """Homogeneous image (4,) of a point or direction (4,)."""
    return m @ np.asarray(p, np.float64)


def test_look_at_puts_the_eye_at_the_origin_looking_down_minus_z():
    eye, target, up = np.array([1.0, 2.0, 3.0]), np.array([4.0, 2.0, -1.0]), np.array([0.0, 1.0, 0.0])
    v = tf.look_at(eye, target, up)
    assert np.allclose(tf.transform_points(v, eye[None]), 0)
    assert np.allclose(tf.transform_points(v, target[None])[0], [0, 0, -5.0])  # |target - eye| = 5
    assert tf.transform_points(v, (eye + up)[None])[0, 1] > 0                   # up stays up
    right = np.cross(target - eye, up)
    assert tf.transform_points(v, (eye + right)[None])[0, 0] > 0                # right-handed
    assert np.allclose(v[:3, :3] @ v[:3, :3].T, np.eye(3))                      # rigid


def test_look_along_handles_vertical_directions():
    v = tf.look_along([0.0, 5.0, 0.0], [0.0, -1.0, 0.0])
    assert np.all(np.isfinite(v))
    assert np.allclose(tf.transform_points(v, np.array([[0.0, 2.0, 0.0]]))[0], [0, 0, -3.0])


def test_perspective_maps_near_far_and_the_field_of_view():
    fov, aspect, near, far = 60.0, 1.5, 0.5, 20.0
    p = tf.perspective(fov, aspect, near, far)
    t = np.tan(np.radians(fov / 2))
    assert tf.transform_points(p, np.array([[0, 0, -near]]))[0, 2] == pytest.approx(-1.0)
    assert tf.transform_points(p, np.array([[0, 0, -far]]))[0, 2] == pytest.approx(1.0)
    top_right = tf.transform_points(p, np.array([[near * t * aspect, near * t, -near]]))[0]
    assert np.allclose(top_right, [1.0, 1.0, -1.0])


def test_infinite_projection_keeps_points_at_infinity_inside():
    """Everitt & Kilgard: w = 0 points land at window depth 1 − ε/2, inside the far plane."""
    eps = 2.4e-7
    p = tf.perspective_infinite(45.0, 1.0, 0.1, eps)
    c = apply(p, [0.3, -0.2, -1.0, 0.0])
    assert c[3] > 0 and (c[2] / c[3] + 1) / 2 == pytest.approx(1 - eps / 2, abs=1e-12)
    assert tf.transform_points(p, np.array([[0, 0, -0.1]]))[0, 2] == pytest.approx(-1.0)


def test_orthographic_maps_its_box_to_the_unit_cube():
    o = tf.orthographic(-2.0, 4.0, -1.0, 3.0, 0.5, 10.0)
    corners = np.array([[-2.0, -1.0, -0.5], [4.0, 3.0, -10.0]])
    assert np.allclose(tf.transform_points(o, corners), [[-1, -1, -1], [1, 1, 1]])


def test_euler_angles_turn_about_fixed_x_then_y_then_z():
    assert np.allclose(tf.euler_xyz([0, 90, 0]) @ [1, 0, 0], [0, 0, -1])
    assert np.allclose(tf.euler_xyz([90, 0, 0]) @ [0, 1, 0], [0, 0, 1])
    # x first (y → z), then y (z → x): a different result from the other order
    assert np.allclose(tf.euler_xyz([90, 90, 0]) @ [0, 1, 0], [1, 0, 0])


def test_bias_maps_clip_cube_to_texture_space():
    assert np.allclose(tf.transform_points(tf.BIAS, np.array([[-1, -1, -1], [1, 1, 1.0]])), [[0, 0, 0], [1, 1, 1]])


def test_transform_points_divides_by_w():
    m = np.eye(4)
    m[3, 3] = 2.0
    assert np.allclose(tf.transform_points(m, np.array([[2.0, 4.0, 6.0]])), [[1, 2, 3]])
