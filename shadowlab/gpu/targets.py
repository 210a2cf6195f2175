"""Render targets: checked framebuffers, depth textures of a chosen precision, colour targets
with a shareable depth-stencil attachment, visibility images, read-backs and the full-screen
quad.

:func:`framebuffer` checks completeness; :class:`DepthTexture` is 16-bit, 24-bit fixed point
or 32-bit float; :class:`ScreenTarget` holds colour attachments and a depth-stencil
renderbuffer another target may share; :func:`visibility_target` is a technique's visibility
image; :func:`park` binds the framebuffer that keeps moderngl's current one a live name.

What moderngl has no API for — depth-stencil attachments, stencil state, depth formats — is
made with PyOpenGL and wrapped by ``ctx.detect_framebuffer`` so that both libraries can use it.
GL's window origin is the bottom-left pixel; every array this module returns is flipped so
that row 0 is the *top* of the image (docs/architecture.md#conventions).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gl import GLError, check_errors, context

_PARKING = None


def park() -> None:
    """Bind a 1x1 framebuffer that lives as long as the context. moderngl re-binds its current
    framebuffer after creating or using others, so whoever deletes framebuffers calls this
    first: the current one is then never a deleted name (INVALID_OPERATION on the next
    moderngl framebuffer otherwise). EGL standalone contexts have no default framebuffer."""
    global _PARKING
    ctx = context()
    if _PARKING is None:
        _PARKING = framebuffer([ctx.renderbuffer((1, 1))])
    _PARKING.use()


_DEPTH_FORMATS = {16: "GL_DEPTH_COMPONENT16", 24: "GL_DEPTH_COMPONENT24", 32: "GL_DEPTH_COMPONENT32F"}


@dataclass
class DepthTexture:
    """A depth texture of 16, 24 (fixed point) or 32 (float) bits, sampled with texelFetch/texture.

    ``texture`` is a moderngl wrapper (``.use(unit)``); ``fbo`` renders depth only into it.
    """

    size: tuple[int, int]
    bits: int
    glo: int
    texture: object
    fbo: object
    fbo_glo: int

    @classmethod
    def create(cls, size: tuple[int, int], bits: int) -> "DepthTexture":
        """Allocate a ``size`` = (width, height) depth texture with ``bits`` in {16, 24, 32}."""
        from OpenGL import GL

        if bits not in _DEPTH_FORMATS:
            raise ValueError(f"depth_bits must be one of {sorted(_DEPTH_FORMATS)}, got {bits}")
        ctx = context()
        w, h = size
        tid = int(GL.glGenTextures(1))
        GL.glBindTexture(GL.GL_TEXTURE_2D, tid)
        GL.glTexImage2D(GL.GL_TEXTURE_2D, 0, getattr(GL, _DEPTH_FORMATS[bits]), w, h, 0,
                        GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, None)
        for pname in (GL.GL_TEXTURE_MIN_FILTER, GL.GL_TEXTURE_MAG_FILTER):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, pname, GL.GL_NEAREST)
        for pname in (GL.GL_TEXTURE_WRAP_S, GL.GL_TEXTURE_WRAP_T):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, pname, GL.GL_CLAMP_TO_EDGE)
        GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_COMPARE_MODE, GL.GL_NONE)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        fid = int(GL.glGenFramebuffers(1))
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fid)
        GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_TEXTURE_2D, tid, 0)
        GL.glDrawBuffer(GL.GL_NONE)
        GL.glReadBuffer(GL.GL_NONE)
        _check_complete(GL)
        fbo = ctx.detect_framebuffer(fid)
        tex = ctx.external_texture(tid, (w, h), 1, 0, "f4")
        check_errors("DepthTexture.create")
        return cls((w, h), bits, tid, tex, fbo, fid)

    @property
    def nbytes(self) -> int:
        """GPU memory of the texture in bytes (24-bit formats are counted as stored, 4 bytes)."""
        per = {16: 2, 24: 4, 32: 4}[self.bits]
        return self.size[0] * self.size[1] * per

    def use_as_target(self) -> None:
        """Bind for a depth-only pass and set the viewport to the whole texture."""
        self.fbo.use()
        context().viewport = (0, 0, *self.size)

    def read(self) -> np.ndarray:
        """Depth values as float32 (height, width), row 0 = top (slow; for tests and debugging)."""
        return _read_pixels(self.fbo_glo, self.size, "depth")

    def release(self) -> None:
        """Free the GL objects."""
        from OpenGL import GL

        GL.glDeleteFramebuffers(1, [self.fbo_glo])
        GL.glDeleteTextures(1, [self.glo])


def _read_pixels(fbo_glo: int, size: tuple[int, int], what: str) -> np.ndarray:
    """Depth (float32) or stencil (uint8) of a framebuffer as (height, width), row 0 = top."""
    from OpenGL import GL

    fmt, gltype, dtype = {"depth": (GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, np.float32),
                          "stencil": (GL.GL_STENCIL_INDEX, GL.GL_UNSIGNED_BYTE, np.uint8)}[what]
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fbo_glo)
    GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
    data = GL.glReadPixels(0, 0, size[0], size[1], fmt, gltype)
    return np.frombuffer(data, dtype).reshape(size[1], size[0])[::-1].copy()


def _check_complete(GL) -> None:
    status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
    if status != GL.GL_FRAMEBUFFER_COMPLETE:
        raise GLError(f"framebuffer incomplete (status {hex(int(status))})")


@dataclass
class ScreenTarget:
    """Colour attachments plus a 24-bit depth / 8-bit stencil renderbuffer, at screen size.

    The G-buffer lives here; techniques that need the stencil (shadow volumes) use
    :meth:`read_stencil` and PyOpenGL's stencil calls while this target is bound.
    """

    size: tuple[int, int]
    colors: list
    fbo: object
    fbo_glo: int
    depth_stencil_glo: int
    owns_depth_stencil: bool = True

    @classmethod
    def create(cls, size: tuple[int, int], colors: list, share_depth_stencil: "ScreenTarget | None" = None
               ) -> "ScreenTarget":
        """Wrap moderngl textures ``colors`` (all of ``size``) with a new depth-stencil attachment,
        or with the one of ``share_depth_stencil`` (e.g. a technique drawing on the G-buffer's stencil)."""
        from OpenGL import GL

        ctx = context()
        w, h = size
        fid = int(GL.glGenFramebuffers(1))
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fid)
        for i, tex in enumerate(colors):
            GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0 + i, GL.GL_TEXTURE_2D, tex.glo, 0)
        GL.glDrawBuffers(len(colors), [GL.GL_COLOR_ATTACHMENT0 + i for i in range(len(colors))])
        if share_depth_stencil is not None:
            if tuple(share_depth_stencil.size) != (w, h):
                raise ValueError(f"shared depth-stencil is {share_depth_stencil.size}, target is {size}")
            rb = share_depth_stencil.depth_stencil_glo
        else:
            rb = int(GL.glGenRenderbuffers(1))
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, rb)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_DEPTH24_STENCIL8, w, h)
        GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_STENCIL_ATTACHMENT, GL.GL_RENDERBUFFER, rb)
        _check_complete(GL)
        fbo = ctx.detect_framebuffer(fid)
        check_errors("ScreenTarget.create")
        return cls((w, h), list(colors), fbo, fid, rb, share_depth_stencil is None)

    def use(self) -> None:
        """Bind as the draw target with a full-size viewport."""
        self.fbo.use()
        context().viewport = (0, 0, *self.size)

    def clear_depth_stencil(self, depth: float = 1.0, stencil: int = 0) -> None:
        """Clear depth and stencil of this target (it must be bound, and the pass state applied:
        rasterizer discard off). Sets the depth and stencil write masks to all-on."""
        from OpenGL import GL

        GL.glDepthMask(GL.GL_TRUE)
        GL.glStencilMask(0xFF)
        GL.glClearDepth(depth)
        GL.glClearStencil(stencil)
        GL.glClear(GL.GL_DEPTH_BUFFER_BIT | GL.GL_STENCIL_BUFFER_BIT)

    def read_stencil(self) -> np.ndarray:
        """The stencil buffer as uint8 (height, width), row 0 = top."""
        return _read_pixels(self.fbo_glo, self.size, "stencil")

    def release(self) -> None:
        """Free the framebuffer and its own depth-stencil renderbuffer (not colour textures, not a shared one)."""
        from OpenGL import GL

        GL.glDeleteFramebuffers(1, [self.fbo_glo])
        if self.owns_depth_stencil:
            GL.glDeleteRenderbuffers(1, [self.depth_stencil_glo])


def framebuffer(color_attachments: list, depth_attachment=None):
    """A moderngl framebuffer, checked complete (GLError otherwise)."""
    from OpenGL import GL

    ctx = context()
    fbo = ctx.framebuffer(color_attachments=color_attachments, depth_attachment=depth_attachment)
    current = ctx.fbo  # moderngl re-bound its current framebuffer (if any) after creating this one
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fbo.glo)
    try:
        _check_complete(GL)
    finally:
        (current or fbo).use()
    return fbo


def visibility_target(size: tuple[int, int]):
    """A technique's visibility image: an R32F texture of ``size`` (width, height) and a checked
    framebuffer drawing into it, as (texture, framebuffer)."""
    tex = context().texture(tuple(size), 1, dtype="f4")
    return tex, framebuffer([tex])


def read_texture(tex, components: int, dtype: str = "f4") -> np.ndarray:
    """A moderngl texture as an array (height, width, components), row 0 = top."""
    w, h = tex.size
    data = np.frombuffer(tex.read(), dtype=np.dtype(dtype))
    return data.reshape(h, w, components)[::-1].copy()


_FULLSCREEN_VBO = None


def fullscreen_quad(prog):
    """A VertexArray drawing one screen-covering triangle pair; ``prog`` needs ``in vec2 in_pos``.
    Every quad reads one vertex buffer that lives as long as the context (releasing the
    VertexArray leaves it for the next quad)."""
    global _FULLSCREEN_VBO
    ctx = context()
    if _FULLSCREEN_VBO is None:
        _FULLSCREEN_VBO = ctx.buffer(np.array([-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1], dtype="f4").tobytes())
    return ctx.vertex_array(prog, [(_FULLSCREEN_VBO, "2f", "in_pos")])
