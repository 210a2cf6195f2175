"""The viewer's window: ``shadowlab view SCENE`` (docs/your-scenes.md#the-viewer).

The window is moderngl-window's pyglet window (optional extra ``viewer``): moderngl-window gives a
moderngl context on the window, so the window draws with the same API as the lab, and pyglet
needs no system library beyond X11 and GL (no SDL, no Qt, no GLFW build), so it runs under Xvfb
with Mesa's llvmpipe as the lab's tests do. The window shows one texture: the picture
:class:`shadowlab.viewer.render.LabRenderer` made on the lab's headless context, with the HUD
drawn into it (Pillow's default font), uploaded to the window's context and drawn at exactly
one texel per pixel — so a screenshot with the HUD off is the lab's picture itself.

The loop, one iteration per frame: take the input (the keyboard and mouse, or the ``--script``
steps due at this frame), advance the :class:`shadowlab.viewer.state.ViewState` (wall-clock time
step; a script's fixed one), make a new lab frame where the camera moved, compute the truth
where the camera has been still long enough (drawing "truth: computing" first), draw the view
and the HUD, take a screenshot if one is due, swap. Each iteration's times are recorded
(:data:`FRAME_TIME_COLUMNS`; script step ``frame_times``).
"""
from __future__ import annotations

import csv
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..techniques import TechniqueError
from ..util.validation import RunError
from .render import LabRenderer, to_bytes
from .scene_file import save_view
from .script import Script
from .state import KEYMAP, MOVE_KEYS, SCRIPT_DT, ViewState, default_speed

#: What to do on a machine with no display (the one line ``shadowlab view`` prints there).
XVFB_HINT = ("run it under a virtual X server: xvfb-run shadowlab view ... (Debian/Ubuntu: apt-get install xvfb), "
             "or on a machine with a display")
#: The columns of a frame-times CSV (script step ``frame_times``), one row per frame drawn:
#: the frame number, the configuration and view shown, whether the camera moved in it, the new
#: lab frame's wall time (G-buffer and exact points; 0 when the camera stood still), the
#: technique's timed render summed over the lights (the pipeline's ``time_ms_median`` of a
#: one-render measurement; blank when nothing was measured in this frame), the wall time of all
#: lab work in it (frame, set-up, render, shading, truth) and of the whole iteration (input,
#: lab work, HUD, upload, draw, swap; idle sleep excluded).
FRAME_TIME_COLUMNS = ("frame", "config", "view", "camera_moved", "frame_ms", "render_ms", "lab_ms", "loop_ms")
#: Seconds an interactive loop sleeps when nothing moves (keeps an idle window off the CPU).
IDLE_SLEEP = 1.0 / 60.0


class NoDisplay(RuntimeError):
    """No window can be opened here (no display, or moderngl-window / pyglet missing): the
    message says what to install or do."""


def _key_names(keys) -> dict:
    """moderngl-window key constant → the names of :data:`shadowlab.viewer.state.KEYMAP` and
    :data:`MOVE_KEYS` (plus ``shift`` for either shift key)."""
    names = {}
    for letter in "abcdefghijklmnopqrstuvwxyz":
        names[getattr(keys, letter.upper())] = letter
    for n in range(10):
        names[getattr(keys, f"NUMBER_{n}")] = str(n)
    for n in range(1, 13):
        names[getattr(keys, f"F{n}")] = f"f{n}"
    for const, name in (("TAB", "tab"), ("ESCAPE", "escape"), ("BACKSPACE", "backspace"),
                        ("LEFT_SHIFT", "shift"), ("RIGHT_SHIFT", "shift")):
        names[getattr(keys, const)] = name
    return names


def open_window(size: tuple[int, int], title: str):
    """A moderngl-window pyglet window of exactly ``size`` pixels (not resizable, no vsync: the
    loop's frame time is the viewer's own). NoDisplay, with what to do, where none can be made."""
    if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        raise NoDisplay(f"no display to open the viewer's window on (DISPLAY is not set); {XVFB_HINT}")
    try:
        import moderngl_window  # noqa: F401
    except ImportError as exc:
        raise NoDisplay(f"the viewer needs moderngl-window ({exc.name or exc} is missing): "
                        f"pip install 'shadowlab[viewer]'") from exc
    try:
        from moderngl_window.context.pyglet import Window

        window = Window(title=title, size=size, resizable=False, vsync=False, gl_version=(3, 3),
                        aspect_ratio=None, visible=True)
    except Exception as exc:  # pyglet raises its own types (NoSuchDisplayException, WindowException, ...)
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise NoDisplay(f"cannot open a window on display {os.environ.get('DISPLAY')!r} ({reason}); "
                        f"{XVFB_HINT}") from exc
    return window


class Screen:
    """What the window draws: one RGB texture, one texel per pixel, drawn by the lab's
    full-screen quad with ``screen.glsl``; and its read-back for screenshots. It draws on the
    window's context, which is also the lab's (:func:`shadowlab.gpu.gl.adopt`): every draw binds the window's framebuffer and
    applies a full pass state first, as every lab pass does (nothing is inherited either way)."""

    def __init__(self, window, size: tuple[int, int]):
        self.window, self.size = window, size
        from ..gpu import programs, targets

        ctx = window.ctx
        # the lab's loader and full-screen quad: the window's context is the lab's (gl.adopt)
        self.prog = programs.program("screen.glsl")
        self.texture = ctx.texture(size, 3, dtype="f1")
        self.texture.filter = (ctx.NEAREST, ctx.NEAREST)
        self.vao = targets.fullscreen_quad(self.prog)

    def draw(self, picture: np.ndarray) -> None:
        """Show ``picture``: uint8 (H, W, 3), row 0 = top."""
        from ..gpu import glstate

        ctx = self.window.ctx
        self.texture.write(np.ascontiguousarray(picture[::-1]).tobytes())  # GL's row 0 is the bottom
        ctx.screen.use()
        bw, bh = self.window.buffer_size
        ctx.viewport = (0, 0, bw, bh)
        glstate.apply(glstate.PassState(depth_write=False))
        self.prog["u_scale"].value = (self.size[0] / bw, self.size[1] / bh)
        self.texture.use(0)
        self.prog["u_image"].value = 0
        self.vao.render()

    def read(self) -> np.ndarray:
        """The window as drawn (the back buffer, before the swap): uint8 (H, W, 3), row 0 = top.
        Read with glReadPixels from GL_BACK: moderngl's read of the default framebuffer selects
        a colour attachment it does not have (GL_INVALID_OPERATION, which the lab's next error
        check would blame on a technique)."""
        from OpenGL import GL

        w, h = self.window.buffer_size
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, 0)
        GL.glReadBuffer(GL.GL_BACK)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        data = GL.glReadPixels(0, 0, w, h, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
        return np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1].copy()

    def swap(self) -> None:
        """Show the drawn frame and take the window's events."""
        self.window.swap_buffers()


def hud_picture(picture: np.ndarray, lines: list[str]) -> np.ndarray:
    """``picture`` (uint8 (H, W, 3)) with ``lines`` of text over a dark band at its top-left."""
    if not lines:
        return picture
    from PIL import Image, ImageDraw, ImageFont

    image = Image.fromarray(picture)
    draw = ImageDraw.Draw(image, "RGBA")
    font = ImageFont.load_default(size=11)
    line_h = 13
    width = max(draw.textlength(line, font=font) for line in lines)
    draw.rectangle((0, 0, int(width) + 8, line_h * len(lines) + 6), fill=(0, 0, 0, 150))
    for k, line in enumerate(lines):
        draw.text((4, 3 + k * line_h), line, font=font, fill=(255, 255, 255, 255))
    return np.asarray(image)


def greyed(rgb: np.ndarray) -> np.ndarray:
    """A picture shown while it is out of date: its grey levels, faded (float (H, W, 3))."""
    grey = np.asarray(rgb, np.float64).mean(axis=2, keepdims=True)
    return np.repeat(0.25 + 0.4 * grey, 3, axis=2)


@dataclass
class FrameTime:
    """One row of :data:`FRAME_TIME_COLUMNS`."""

    frame: int
    config: str
    view: str
    camera_moved: bool
    frame_ms: float
    render_ms: float | None
    lab_ms: float
    loop_ms: float


def write_frame_times(rows: list[FrameTime], path: Path) -> None:
    """The frame-time rows as CSV (:data:`FRAME_TIME_COLUMNS`), times to 0.01 ms."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(FRAME_TIME_COLUMNS)
        for r in rows:
            out.writerow([r.frame, r.config, r.view, int(r.camera_moved), f"{r.frame_ms:.2f}",
                          "" if r.render_ms is None else f"{r.render_ms:.2f}", f"{r.lab_ms:.2f}", f"{r.loop_ms:.2f}"])


def frame_time_summary(rows: list[FrameTime]) -> list[str]:
    """Per configuration, the medians over the frames in which the camera moved: the viewer loop's
    ms per frame and the technique's render (the lines printed at exit)."""
    out = []
    for spec in dict.fromkeys(r.config for r in rows):
        moving = [r for r in rows if r.config == spec and r.camera_moved]
        if not moving:
            continue
        loop = float(np.median([r.loop_ms for r in moving]))
        renders = [r.render_ms for r in moving if r.render_ms is not None]
        render = f", technique render {np.median(renders):.1f} ms" if renders else ""
        out.append(f"{spec}: {loop:.1f} ms per frame with the camera moving ({1e3 / loop:.1f} frames/s{render}; "
                   f"median of {len(moving)} frames)")
    return out


class Viewer:
    """The window, the lab renderer and the view state, and the loop between them
    (:meth:`run`). ``out`` is where screenshots and saved views go (named files are relative to
    it); ``script`` drives it instead of a person (:mod:`shadowlab.viewer.script`)."""

    def __init__(self, scene, specs: list[str], size: tuple[int, int], view: str = "shaded", hud: bool = True,
                 out: Path = Path("."), script: Script | None = None):
        self.scene, self.size, self.out, self.script = scene, size, Path(out), script
        self.state = ViewState(list(specs), scene.camera, default_speed(scene.extent()), view=view, hud=hud)
        # the window first, and its context becomes the lab's (shadowlab.gpu.gl.adopt) before any GL work
        self.window = open_window(size, f"shadowlab view — {scene.name}")
        from ..gpu import gl

        gl.adopt(self.window.ctx)
        self.screen = Screen(self.window, size)
        self.renderer = LabRenderer(scene, list(specs), size)
        self.key_names = _key_names(self.window.keys)
        self.held: set[str] = set()
        self.pressed: list[str] = []
        self.drag_accum = [0.0, 0.0]
        self.dragging = False
        self.frame_times: list[FrameTime] = []
        self.last_pictures: dict[str, np.ndarray] = {}
        self.truth_pending = False
        self.shots = 0
        self.saves = 0
        self.messages: list[str] = []
        w = self.window
        w.key_event_func = self._on_key
        w.mouse_press_event_func = self._on_press
        w.mouse_release_event_func = self._on_release
        w.mouse_drag_event_func = self._on_drag

    # ------------------------------------------------------------------ input (interactive)
    def _on_key(self, key, action, modifiers) -> None:
        name = self.key_names.get(key)
        if name is None:
            return
        if action == self.window.keys.ACTION_PRESS:
            if name in MOVE_KEYS or name == "shift":
                self.held.add(name)
            else:
                shifted = f"shift+{name}"
                self.pressed.append(shifted if modifiers.shift and shifted in KEYMAP else name)
        elif action == self.window.keys.ACTION_RELEASE:
            self.held.discard(name)

    def _on_press(self, x, y, button) -> None:
        self.dragging = self.dragging or button == 1

    def _on_release(self, x, y, button) -> None:
        if button == 1:
            self.dragging = False

    def _on_drag(self, x, y, dx, dy) -> None:
        if self.dragging:
            self.drag_accum[0] += dx
            self.drag_accum[1] += dy

    # ------------------------------------------------------------------ files
    def _path(self, name: str | None, stem: str, suffix: str) -> Path:
        if name is not None:
            return self.out / name
        return self.out / f"{stem}{suffix}"

    def screenshot(self, picture: np.ndarray, name: str | None = None) -> Path:
        """Save the window's picture (uint8 (H, W, 3)) as a PNG; print its name."""
        from PIL import Image

        self.shots += 1
        path = self._path(name, f"view-{self.scene.name}-{self.shots:03d}", ".png")
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(picture).save(path)
        print(f"screenshot: {path}")
        return path

    def save_view(self, name: str | None = None) -> Path | None:
        """Save the current view as a scene file; print its name (or, for a view that cannot be
        saved, why: shown in the HUD too)."""
        self.saves += 1
        path = self._path(name, f"view-{self.scene.name}-{self.saves:03d}", ".toml")
        try:
            save_view(self.scene, self.state.fly.camera(), path)
        except RunError as exc:
            self.messages = [f"save view: {exc}"]
            print(f"shadowlab: {exc}", file=sys.stderr)
            return None
        print(f"view: {path}")
        self.messages = [f"saved {path.name}"]
        return path

    # ------------------------------------------------------------------ the loop
    def run(self) -> int:
        """Run until the window closes or the script quits; 0."""
        frame, last = 0, time.perf_counter()
        try:
            while not self.window.is_closing:
                t0 = time.perf_counter()
                dt = SCRIPT_DT if self.script is not None else t0 - last
                last = t0
                if not self._iterate(frame, dt, t0):
                    break
                frame += 1
        finally:
            self.renderer.release()
            self.window.destroy()
        for line in frame_time_summary(self.frame_times):
            print(f"frame times: {line}")
        return 0

    def _inputs(self, frame: int):
        """This frame's key presses, held movement keys, shift, drag and script steps."""
        steps = []
        if self.script is not None:
            steps = self.script.instants(frame)
            held, fast = self.script.held(frame)
            drag = self.script.drag(frame)
            presses = [s.value for s in steps if s.kind == "key"]
        else:
            presses, self.pressed = self.pressed, []
            held, fast = self.held - {"shift"}, "shift" in self.held
            drag, self.drag_accum = tuple(self.drag_accum), [0.0, 0.0]
        return presses, held, fast, drag, steps

    def _iterate(self, frame: int, dt: float, t0: float) -> bool:
        state, renderer = self.state, self.renderer
        presses, held, fast, drag, steps = self._inputs(frame)
        effects, shots = [], []
        # script steps in file order: a key before a screenshot at the same frame is in the picture
        for step in steps:
            if step.kind == "quit":
                return False
            if step.kind == "screenshot":
                shots.append(step.value)
            elif step.kind == "wait_truth":
                effects.append("truth_now")
            elif step.kind == "save_view":
                effects.append(("save_view", step.value))
            elif step.kind == "frame_times":
                write_frame_times(self.frame_times, self.out / step.value)
                print(f"frame times: {self.out / step.value}")
        for key in presses:
            effects.extend(state.press(key))
        moved = state.step(dt, held, drag, fast)
        lab0 = time.perf_counter()
        made = renderer.look_from(state.fly.camera(), state.camera_version)
        if made:
            self.truth_pending = False
        if "truth_now" in effects or self.truth_pending:
            renderer.truth()
            self.truth_pending = False
        renderer.take_measured()
        shaded, notes = None, []
        try:
            picture, note = renderer.picture(state.view, state.config)
            images = renderer.images(state.config)
            shaded, notes = images.shaded, images.notes[:1]
        except TechniqueError as exc:  # a configuration that cannot render from here: said, not fatal
            picture, note = None, f"cannot render here: {exc}"
        measured = renderer.take_measured()
        lab_ms = 1e3 * (time.perf_counter() - lab0)
        if picture is None:
            # out of date or not applicable: the last picture of this view (another camera's), else the
            # configuration's shaded one, greyed
            base = self.last_pictures.get(state.view) if state.view in ("truth", "error") else None
            base = base if base is not None else shaded if shaded is not None else np.zeros((self.size[1],
                                                                                             self.size[0], 3))
            picture = greyed(base)
        else:
            self.last_pictures[state.view] = picture
        if not renderer.has_truth and state.truth_due():
            self.truth_pending = True  # drawn with "computing" now, computed before the next frame
        for effect in effects:
            if effect == "quit":
                return False
            if effect == "save_view":
                self.save_view()
            elif isinstance(effect, tuple) and effect[0] == "save_view":
                self.save_view(effect[1])
        shown = to_bytes(picture)
        if state.hud:
            shown = hud_picture(shown, self._hud_lines(note, notes))
        self.screen.draw(shown)
        if "screenshot" in effects or shots:
            window_picture = self.screen.read()
            if "screenshot" in effects:
                self.screenshot(window_picture)
            for name in shots:
                self.screenshot(window_picture, name)
        self.screen.swap()
        loop_ms = 1e3 * (time.perf_counter() - t0)
        render_ms = sum(m.render_ms for m in measured) if measured else None
        self.frame_times.append(FrameTime(frame, state.spec, state.view, moved,
                                          renderer.frame_ms if made else 0.0, render_ms, lab_ms, loop_ms))
        if self.script is None and not (moved or held or self.truth_pending):
            time.sleep(IDLE_SLEEP)
        return True

    def _hud_lines(self, note: str, notes: list[str]) -> list[str]:
        state, renderer = self.state, self.renderer
        images = renderer.cached(state.config)
        last = self.frame_times[-1] if self.frame_times else None
        lines = [f"[{state.config + 1}/{len(state.specs)}] {state.spec}",
                 f"view: {state.view}" + (f" - {note}" if note else "")]
        timing = []
        if images is not None:
            timing.append(f"render {images.render_ms:.1f} ms")
        if last is not None:
            timing.append(f"loop {last.loop_ms:.0f} ms/frame")
        if timing:
            lines.append(" | ".join(timing))
        if self.truth_pending:
            lines.append("truth: computing...")
        else:
            error = renderer.error_rate(state.config) if renderer.has_truth else None
            lines.append(f"error (light 0): {100 * error:.3f} %" if error is not None
                         else "error: no truth for this camera yet")
        lines.extend(notes)
        lines.extend(self.messages)
        return lines


#: The configurations ``shadowlab view`` shows when given none, in order: those of them that
#: render for every light of the scene (:meth:`shadowlab.techniques.base.Technique.supports`,
#: the pipeline's light check).
DEFAULT_SPECS = ("shadow_map", "shadow_volume", "cascaded_map", "pcss", "filtered_map", "virtual_map")


def default_specs(scene) -> list[str]:
    """:data:`DEFAULT_SPECS` that render for every light of ``scene``."""
    from ..techniques import technique_class

    return [s for s in DEFAULT_SPECS if all(technique_class(s).supports(light) for light in scene.lights)]


def view(scene_ref, specs: list[str] | None, size: tuple[int, int], view_name: str = "shaded",
         screenshot: str | None = None, script: str | None = None, out: Path = Path("."), hud: bool = True) -> int:
    """``shadowlab view``: check the scene, the configurations and the script as compare checks
    its arguments (SceneError / TechniqueError / RunError, one line, before any window or GL),
    open the window (NoDisplay where none can be), run the loop; the exit status.
    ``screenshot``: draw the first frame with the truth computed, save it there and quit."""
    from ..measurement.pipeline import build_techniques, check_lights
    from ..measurement.scenes import load_measured_scene
    from ..util.validation import check_size
    from .script import Step, load_script

    size = check_size(size)
    scene = load_measured_scene(scene_ref)
    specs = list(specs) if specs else default_specs(scene)
    if not specs:
        raise RunError(f"no default configuration renders for every light of {scene.name}; give some with -t")
    check_lights(build_techniques(specs), scene)
    if screenshot is not None and script is not None:
        raise RunError("give --screenshot or --script, not both (a script takes screenshots with its own steps)")
    plan = None
    if script is not None:
        plan = load_script(script)
    elif screenshot is not None:
        plan = Script([Step("wait_truth", True, 0), Step("screenshot", str(Path(screenshot).resolve()), 0),
                       Step("quit", True, 1)])
    return Viewer(scene, specs, size, view=view_name, hud=hud, out=out, script=plan).run()
