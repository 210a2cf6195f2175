"""The GL harness: context, shader includes, the depth-stencil attachment, depth formats."""
from __future__ import annotations

import numpy as np
import pytest
from OpenGL import GL

from shadowlab.gpu import gl, glsl, programs, targets



def _names_location(message: str, where: str) -> bool:
    """True when ``message`` names ``where`` (file.glsl:line) as a location: Mesa writes
    ``file.glsl:8(5)`` (with a column), NVIDIA ``file.glsl:8 :``."""
    import re

    return re.search(re.escape(where) + r"[( ]", message) is not None

def test_context_and_renderer(ctx):
    assert ctx.version_code >= 330
    assert isinstance(gl.renderer(), str) and gl.renderer()


def test_include_expands_and_stages_compile(ctx):
    src = glsl.shader_source("shade.glsl")
    assert "light_footprint" in src and "#include" not in src
    prog = programs.program("shade.glsl")
    assert "u_visibility" in prog


def test_stencil_round_trip(ctx):
    """Write the stencil with INCR_WRAP from two overlapping quads, then test EQUAL against it."""
    w, h = 64, 32
    color = ctx.texture((w, h), 4, dtype="f4")
    target = targets.ScreenTarget.create((w, h), [color])
    target.use()
    target.clear_depth_stencil()
    prog = ctx.program(vertex_shader="#version 330\nin vec2 in_pos; uniform float u_off; uniform float u_scale;"
                                     "void main(){gl_Position=vec4(in_pos.x*u_scale+u_off,in_pos.y,0.0,1.0);}",
                       fragment_shader="#version 330\nuniform vec4 u_col; out vec4 c; void main(){c=u_col;}")
    quad = targets.fullscreen_quad(prog)
    prog["u_col"].value = (0, 0, 0, 0)
    GL.glDisable(GL.GL_DEPTH_TEST)  # whatever an earlier test left: both quads must reach the stencil op
    GL.glStencilMask(0xFF)
    GL.glEnable(GL.GL_STENCIL_TEST)
    GL.glStencilFunc(GL.GL_ALWAYS, 0, 0xFF)
    GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_INCR_WRAP)
    # left half, then left quarter: counts 2 on the left quarter, 1 on the second quarter
    for scale, off in ((0.5, -0.5), (0.25, -0.75)):
        prog["u_scale"].value, prog["u_off"].value = scale, off
        quad.render()
    stencil = target.read_stencil()
    assert stencil[:, : w // 4].min() == 2 and stencil[:, w // 4: w // 2].max() == 1 and stencil[:, w // 2:].max() == 0
    target.use()
    GL.glStencilFunc(GL.GL_EQUAL, 2, 0xFF)
    GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_KEEP)
    prog["u_scale"].value, prog["u_off"].value, prog["u_col"].value = 1.0, 0.0, (1, 0, 0, 1)
    quad.render()
    GL.glDisable(GL.GL_STENCIL_TEST)
    img = targets.read_texture(color, 4)
    assert (img[:, : w // 4, 0] == 1).all() and (img[:, w // 4:, 0] == 0).all()
    quad.release(); prog.release(); target.release(); color.release()


@pytest.mark.parametrize("bits,step", [(16, 1 / 65535), (24, 1 / 16777215), (32, 0.0)])
def test_depth_formats_quantise(ctx, bits, step):
    """A cleared depth texture stores the clear value rounded to its format (16-bit: a
    visible step; 24-bit: within a step; 32-bit float: the float32 value)."""
    tex = targets.DepthTexture.create((8, 8), bits)
    tex.use_as_target()
    value = 0.123456789
    GL.glClearDepth(value)
    GL.glClear(GL.GL_DEPTH_BUFFER_BIT)
    got = float(tex.read()[0, 0])
    if bits == 16:
        assert 1e-7 < abs(got - value) <= step / 2 + 1e-9
        assert abs(got / step - round(got / step)) < 1e-3
    elif bits == 24:
        assert abs(got - value) <= step / 2 + 1e-9
    else:
        assert got == pytest.approx(np.float32(value), abs=0)
    GL.glClearDepth(1.0)
    ctx.finish()
    tex.release()


def test_releasing_the_current_framebuffer_leaves_moderngl_usable(ctx):
    """A frame and its shading pass released while one of their framebuffers is current: the
    next moderngl framebuffer must still be created without a GL error (moderngl re-binds its
    current framebuffer, which must never be a deleted name)."""
    from shadowlab.gpu.frame import Frame
    from shadowlab.scene import load_scene
    from shadowlab.gpu.shading import ShadingPass

    frame = Frame(load_scene("box_on_plane"), 32, 24)
    shading = ShadingPass(frame)
    shading.shade([np.ones((24, 32), np.float32)])  # leaves its own framebuffer current
    shading.release()
    frame.release()
    fbo = ctx.framebuffer(color_attachments=[ctx.texture((4, 4), 4)])
    gl.check_errors("new framebuffer after releases")
    fbo.color_attachments[0].release()
    fbo.release()
    targets.park()


# --------------------------------------------------------------------------- shader files

FULLSCREEN = """// test: a full-screen vertex stage
#ifdef VERTEX_SHADER
in vec2 in_pos;
void main() {
    gl_Position = vec4(in_pos, 0.0, 1.0);
}
#endif
"""
HELPER = """// test: a helper function
float helper(float x) {
    return 2.0 * x;
}
"""


@pytest.fixture
def shader_files(tmp_path, monkeypatch):
    """Write test-only GLSL files (name → text) into a temporary folder that is then the
    loader's whole search path (glsl.shader_path()); fullscreen.glsl and helper.glsl are always there."""
    monkeypatch.setattr(glsl, "shader_path", lambda: (tmp_path,))

    def write(**files):
        for name, text in {"fullscreen": FULLSCREEN, "helper": HELPER, **files}.items():
            (tmp_path / f"{name}.glsl").write_text(text)
        return tmp_path
    return write


def build_error(name: str, defines=None) -> str:
    with pytest.raises(glsl.ShaderError) as exc:
        programs.program(name, defines)
    return str(exc.value)


def test_error_after_an_include_names_its_file_and_line(ctx, shader_files):
    shader_files(broken="""// test: an error after two includes
#include "fullscreen.glsl"

#ifdef FRAGMENT_SHADER
#include "helper.glsl"
out float out_value;
void main() {
    out_value = helper(undeclared_name);
}
#endif
""")
    message = build_error("broken.glsl", {"SOME_SWITCH": 1})
    assert "broken.glsl {SOME_SWITCH=1}" in message  # the file and its defines
    assert _names_location(message, "broken.glsl:8") and "undeclared_name" in message, message
    assert not any(f"{n}:8(" in message for n in ("0", "1", "helper.glsl")), message


def test_error_inside_an_include_names_the_included_file(ctx, shader_files):
    shader_files(bad_helper="// test: a broken helper\nfloat helper(float x) {\n    return 2.0 * y;\n}\n",
                 uses_bad="""// test: includes a broken helper
#include "fullscreen.glsl"
#ifdef FRAGMENT_SHADER
#include "bad_helper.glsl"
out float out_value;
void main() { out_value = helper(1.0); }
#endif
""")
    message = build_error("uses_bad.glsl")
    assert _names_location(message, "bad_helper.glsl:3") and "uses_bad.glsl:" not in message, message


def test_line_numbers_survive_an_include_in_a_skipped_group(ctx, shader_files):
    """The vertex stage skips the FRAGMENT_SHADER group, and with it the #line marker after the
    include there: the line after #endif must still be numbered right."""
    shader_files(skipped="""// test: an include in a group the vertex stage skips
#ifdef FRAGMENT_SHADER
#include "helper.glsl"
#endif
#ifdef VERTEX_SHADER
in vec2 in_pos;
void main() {
    gl_Position = vec4(in_pos, 0.0, 1.0) * missing_scale;
}
#endif
""")
    message = build_error("skipped.glsl")
    assert _names_location(message, "skipped.glsl:8") and "missing_scale" in message, message


def test_preprocessor_error_in_an_include_names_it(ctx, shader_files):
    shader_files(stops="// test\n\n#error stop here\n", top="""// test
#include "fullscreen.glsl"
#include "stops.glsl"
""")
    message = build_error("top.glsl")
    assert _names_location(message, "stops.glsl:3") and "stop here" in message, message


def test_a_file_included_twice_is_expanded_once(ctx, shader_files):
    shader_files(shared="// test: defines a function\nfloat shared_fn(float x) { return x + 1.0; }\n",
                 user="// test\n#include \"shared.glsl\"\nfloat user_fn(float x) { return shared_fn(x); }\n",
                 twice="""// test: includes shared.glsl directly and through user.glsl
#include "fullscreen.glsl"
#include "shared.glsl"
#include "user.glsl"
#ifdef FRAGMENT_SHADER
#include "shared.glsl"  // a comment may follow an include
out float out_value;
void main() { out_value = user_fn(shared_fn(1.0)) + undeclared_after_guard; }
#endif
""")
    src = glsl.shader_source("twice.glsl")
    assert src.count("float shared_fn(") == 1 and "#include" not in src
    message = build_error("twice.glsl")  # compiles but for the deliberate error: no redefinition
    assert "redefin" not in message and _names_location(message, "twice.glsl:8"), message


def test_include_cycles_and_conflicting_guards_are_errors(ctx, shader_files):
    shader_files(cycle_a='// test\n#include "cycle_b.glsl"\n', cycle_b='// test\n#include "cycle_a.glsl"\n',
                 branches="""// test: the same file included in both branches
#include "fullscreen.glsl"
#ifdef SOMETHING
#include "helper.glsl"
#else
#include "helper.glsl"
#endif
""")
    with pytest.raises(glsl.ShaderError, match="cycle: cycle_a.glsl -> cycle_b.glsl -> cycle_a.glsl"):
        glsl.shader_source("cycle_a.glsl")
    # the guard would drop the #else branch's copy: an error rather than a silently missing file
    with pytest.raises(glsl.ShaderError, match="branches.glsl:6: helper.glsl was first included under other"):
        glsl.shader_source("branches.glsl")
    with pytest.raises(glsl.ShaderError, match="not found.*nowhere.glsl.*at top_missing.glsl:2"):
        shader_files(top_missing='// test\n#include "nowhere.glsl"\n')
        glsl.shader_source("top_missing.glsl")
    with pytest.raises(glsl.ShaderError, match="malformed.glsl:2: an #include line must read"):
        shader_files(malformed='// test\n#include <helper.glsl>\n')
        glsl.shader_source("malformed.glsl")


def test_stages_come_from_ifdef_lines_not_mentions(ctx, shader_files):
    """A comment naming GEOMETRY_SHADER makes no geometry stage (which, without a main, would
    not compile); the vertex stage of an include counts."""
    from OpenGL import GL

    shader_files(mentions="""// test: no GEOMETRY_SHADER section here; #ifdef GEOMETRY_SHADER in a comment is no line of its own
#include "fullscreen.glsl"
#ifdef FRAGMENT_SHADER
out float out_value;
void main() { out_value = 1.0; }
#endif
""")
    prog = programs.program("mentions.glsl")
    assert GL.glGetProgramiv(prog.glo, GL.GL_ATTACHED_SHADERS) == 2  # vertex and fragment only


def test_unknown_uniforms_are_errors(ctx, shader_files):
    shader_files(uniforms="""// test: uniforms used, unused and behind a define
#include "fullscreen.glsl"
uniform float u_used;
uniform float u_unused, u_also_unused;          // declared, dropped by the compiler
uniform vec4 u_array[3];
#ifdef FANCY
uniform float u_fancy;
#endif
#ifdef FRAGMENT_SHADER
out float out_value;
void main() { out_value = u_used + u_array[2].x; }
#endif
""")
    prog = programs.program("uniforms.glsl")
    info = programs.program_info(prog)
    assert {"u_used", "u_unused", "u_also_unused", "u_array"} <= info.uniforms and "u_fancy" not in info.uniforms
    programs.set_uniforms(prog, {"u_used": 0.5, "u_unused": 1.0, "u_also_unused": 2.0,
                                 "u_array": np.ones((3, 4), np.float32)})  # unused ones: skipped
    assert prog["u_used"].value == 0.5
    with pytest.raises(KeyError) as exc:
        programs.set_uniforms(prog, {"u_usde": 1.0})
    assert "uniforms.glsl" in str(exc.value) and "did you mean 'u_used'" in str(exc.value), str(exc.value)
    with pytest.raises(programs.UnknownUniformError, match="'u_fancy'"):
        programs.set_uniforms(prog, {"u_fancy": 1.0})
    programs.set_uniforms(programs.program("uniforms.glsl", {"FANCY": 1}), {"u_fancy": 1.0})  # declared there


def test_a_misspelt_uniform_of_a_shipped_program_names_the_right_one(ctx):
    with pytest.raises(programs.UnknownUniformError, match=r"shade.glsl \{\} declares no uniform 'u_densty'; did you mean 'u_density'"):
        programs.set_uniforms(programs.program("shade.glsl"), {"u_densty": 0.5})


def test_programs_are_cached_per_file_defines_and_varyings(ctx, shader_files):
    shader_files(cached="""// test
uniform float u_scale;
#ifdef VERTEX_SHADER
in vec3 in_pos;
out float out_scaled;
void main() {
    out_scaled = u_scale * in_pos.x;
    gl_Position = vec4(in_pos * SIDE * u_scale, 1.0);
}
#endif
#ifdef FRAGMENT_SHADER
out float out_value;
void main() { out_value = 1.0; }
#endif
""")
    a = programs.program("cached.glsl", {"SIDE": 1, "OTHER": 2})
    assert programs.program("cached.glsl", {"OTHER": "2", "SIDE": 1}) is a  # defines in canonical form
    assert programs.program("cached.glsl", {"SIDE": 2, "OTHER": 2}) is not a
    assert programs.program("cached.glsl", {"SIDE": 1, "OTHER": 2}, varyings=("out_scaled",)) is not a
    # handed back as freshly linked: uniforms a previous user set are back at 0
    a["u_scale"].value = 3.0
    assert programs.program("cached.glsl", {"SIDE": 1, "OTHER": 2})["u_scale"].value == 0.0
    programs.release_programs()
    b = programs.program("cached.glsl", {"SIDE": 1, "OTHER": 2})
    assert b is not a and b["u_scale"].value == 0.0


def test_real_programs_are_shared_and_frames_keep_drawing(ctx):
    """Two frames draw with the one cached program; each keeps its own vertex array of it."""
    from shadowlab.gpu.frame import Frame
    from shadowlab.scene import load_scene

    prog = programs.program("shadow_depth.glsl")
    assert programs.program("shadow_depth.glsl") is prog and programs.program("shadow_depth.glsl", {"PEEL": 1}) is not prog
    frames = [Frame(load_scene("box_on_plane"), 16, 12) for _ in range(2)]
    try:
        vaos = [f.vertex_array(prog) for f in frames]
        assert vaos[0] is not vaos[1] and frames[0].vertex_array(programs.program("shadow_depth.glsl")) is vaos[0]
    finally:
        for f in frames:
            f.release()
    assert programs.program("shadow_depth.glsl") is prog  # releasing the frames left the program alone


def test_log_locations_of_other_drivers_are_rewritten():
    """Info-log formats of drivers this machine lacks: NVIDIA 'S(L) : error', AMD 'ERROR: S:L:';
    the file comes from the line number (Mesa reports every compiler error as string 0)."""
    exp = glsl.Expansion("", (glsl.PRELUDE, "main.glsl", "inc.glsl"))
    stride = glsl.LINE_STRIDE
    log = (f"0({2 * stride + 7}) : error C1008: undefined variable \"x\"\n"
           f"ERROR: 0:{stride + 12}: 'y' : undeclared identifier\n"
           f"0:{stride + 3}(9): error: `z' undeclared\n"
           "0:2(1): error: bad define\n"
           "vertex shader output 1:2 is no location\n")
    assert exp.rewrite(log).splitlines() == [
        "inc.glsl:7 : error C1008: undefined variable \"x\"",
        "ERROR: main.glsl:12: 'y' : undeclared identifier",
        "main.glsl:3(9): error: `z' undeclared",
        "<prelude>:2(1): error: bad define",
        "vertex shader output 1:2 is no location"]


def test_expansions_end_every_line_and_markers_name_no_source_string():
    """Every shipped shader's expansion, stripped as moderngl strips a stage's source, ends with
    a line that is no directive — the NVIDIA compiler (H200, driver 580.159.04) rejected a
    ``#line`` marker left at the very end of the source (C0115, "#line line number invalid"),
    failing every program — and each marker is ``#line N``."""
    import re

    for path in sorted(glsl.shader_files().values()):
        text = glsl.shader_source(path.name)
        assert not text.strip().splitlines()[-1].lstrip().startswith("#"), path.name
        markers = [line for line in text.splitlines() if line.lstrip().startswith("#line")]
        assert markers, path.name
        bad = [m for m in markers if not re.fullmatch(r"#line \d+", m.strip())]
        assert not bad, f"{path.name}: {bad[:3]}"


def test_no_shipped_shader_writes_a_double_constant_as_a_float_literal():
    """A GLSL literal without a suffix is a float: 1e300 overflows it. Mesa accepts the overflow,
    NVIDIA's compiler rejects the program (C0153, found on a lent H200: the hierarchical volume did
    not build). Any literal past float's range must carry the LF suffix."""
    import re

    literal = re.compile(r"(?<![\w.])(\d+(?:\.\d*)?|\.\d+)[eE]([+-]?\d+)(lf|LF|f|F)?")
    bad = []
    for name, path in glsl.shader_files().items():
        for lineno, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            code = line.split("//")[0]
            for m in literal.finditer(code):
                if abs(int(m.group(2))) > 38 and (m.group(3) or "").lower() != "lf":
                    bad.append(f"{name}:{lineno}: {m.group(0)}")
    assert not bad, "float literals past float's range (add LF): " + ", ".join(bad)
