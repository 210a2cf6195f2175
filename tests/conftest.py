"""Shared fixtures: the GL context, a check that no test leaves a GL error behind, and one
session-wide cache of frames and ground truths (``lab``, a :class:`helpers.Lab`) that every test
module measures through. Plain helpers (sizes, scene builders) are in ``helpers.py``."""
from __future__ import annotations

import numpy as np
import pytest

from helpers import Lab
from shadowlab.gpu import gl, glstate, programs


@pytest.fixture(autouse=True)
def no_gl_errors():
    """Fail any test after which the GL error flag is set."""
    yield
    if gl._CONTEXT is not None:
        gl.check_errors("test")


#: GL types of the sampler uniforms the draw checker follows.
_SAMPLER_2D, _SAMPLER_2D_SHADOW = 0x8B5E, 0x8B62
DRAW_PROBLEMS: list[str] = []


def _check_draw(vao) -> None:
    """Record what is wrong with the GL state for a draw by ``vao``'s program (see
    shadowlab.gpu.glstate.draw_problems): the test that made the draw then fails."""
    prog = vao.program
    info = programs.program_info(prog)
    units = {}
    for name in prog:
        member = prog[name]
        if getattr(member, "gl_type", None) in (_SAMPLER_2D, _SAMPLER_2D_SHADOW):
            units[int(member.value)] = member.gl_type == _SAMPLER_2D_SHADOW
    written = info.clip_distances if info is not None else frozenset()
    for problem in glstate.draw_problems(written, units):
        DRAW_PROBLEMS.append(f"{info.name if info else 'program'} {info.defines if info else ''}: {problem}")


@pytest.fixture(scope="session", autouse=True)
def checked_draws():
    """Every moderngl draw in the test session is checked against the GL 4.5 core rules that
    llvmpipe does not enforce (clip distances written ⇔ enabled, complete framebuffer, sampler
    compare modes): llvmpipe's leniency must not hide what a GPU would do differently."""
    import moderngl

    originals = moderngl.VertexArray.render, moderngl.VertexArray.transform

    def render(self, *a, **k):
        _check_draw(self)
        return originals[0](self, *a, **k)

    def transform(self, *a, **k):
        _check_draw(self)
        return originals[1](self, *a, **k)

    moderngl.VertexArray.render, moderngl.VertexArray.transform = render, transform
    yield
    moderngl.VertexArray.render, moderngl.VertexArray.transform = originals


@pytest.fixture(autouse=True)
def no_bad_draws():
    """Fail any test that made a draw the GL spec leaves ignored or undefined."""
    DRAW_PROBLEMS.clear()
    yield
    problems = list(dict.fromkeys(DRAW_PROBLEMS))
    DRAW_PROBLEMS.clear()
    assert not problems, "draws with GL state the spec does not define:\n" + "\n".join(problems)


@pytest.fixture(scope="session")
def ctx():
    """The lab's headless GL context."""
    return gl.context()


@pytest.fixture(scope="session")
def lab() -> Lab:
    """The session's shared frames and ground truths."""
    return Lab()


@pytest.fixture
def rng():
    """A seeded random generator."""
    return np.random.default_rng(1234)


@pytest.fixture
def registry_snapshot():
    """For tests that define Technique subclasses with a ``name`` (which register themselves):
    the technique registry as it was before the test is put back after it."""
    from shadowlab.techniques import REGISTRY

    saved = dict(REGISTRY)
    yield REGISTRY
    REGISTRY.clear()
    REGISTRY.update(saved)
