"""Shared fixtures: the GL context, and a check that no test leaves a GL error behind."""
from __future__ import annotations

import numpy as np
import pytest

from shadowlab import gl
from shadowlab.scene import parse_scene


@pytest.fixture(autouse=True)
def no_gl_errors():
    """Fail any test after which the GL error flag is set."""
    yield
    if gl._CONTEXT is not None:
        gl.check_errors("test")


@pytest.fixture(scope="session")
def ctx():
    """The lab's headless GL context."""
    return gl.context()


def make_scene(objects, lights, eye=(4.0, 6.0, 7.0), target=(0.0, 0.0, 0.0), fov_y=50.0, name="test"):
    """A Scene from plain dicts, as a scene file would hold them."""
    data = {"name": name, "camera": {"eye": list(eye), "target": list(target), "fov_y": fov_y},
            "lights": lights, "objects": objects}
    return parse_scene(data, f"<{name}>")


@pytest.fixture
def rng():
    """A seeded random generator."""
    return np.random.default_rng(1234)
