"""``shadowlab view --script FILE``: the viewer driven by a file instead of a person (tests,
screenshots for the docs, frame-time measurements).

A script is a TOML file of ``[[step]]`` tables, run in order. Each step happens at a frame
(``frame``: the frame number, counted from 0; default: right after the previous step, i.e. its
frame plus its length in frames) and does exactly one thing:

====================  ==========================================================================
``key = "tab"``       press a key, by the names of :data:`shadowlab.viewer.state.KEYMAP`
``hold = "w"``        hold a movement key (``shift+w``: fast) for ``frames`` frames (default 1)
``drag = [dx, dy]``   drag the mouse by (dx, dy) pixels, spread evenly over ``frames`` frames
``wait_truth = true`` compute the truth for the current camera now, before the frame is drawn
``screenshot = "a.png"``  save the window as drawn at this frame (PNG)
``save_view = "v.toml"``  save the current view as a scene file
``frame_times = "t.csv"`` write the frame times recorded so far (one row per frame drawn)
``quit = true``       stop (the frame is not drawn)
====================  ==========================================================================

Paths are relative to ``--out`` (default: the current directory). The time step of a scripted
run is fixed (:data:`shadowlab.viewer.state.SCRIPT_DT`), so motion, and the stillness after which
the truth is computed, depend only on frame numbers: a script gives the same pictures on every
machine, however fast it renders. A script that does not quit leaves the window open.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..util.validation import SceneError, TableReader, read_toml_file
from .state import KEYMAP, MOVE_KEYS

#: The step kinds, each a key of a ``[[step]]`` table; a step holds exactly one.
KINDS = ("key", "hold", "drag", "wait_truth", "screenshot", "save_view", "frame_times", "quit")
#: The kinds that last ``frames`` frames; the others happen at one frame.
LASTING = ("hold", "drag")


@dataclass(frozen=True)
class Step:
    """One step: its ``kind`` (:data:`KINDS`), its ``value`` (key name, (dx, dy), path, or True),
    the ``frame`` it starts at and how many ``frames`` it lasts (1 for an instant step)."""

    kind: str
    value: object
    frame: int
    frames: int = 1


class Script:
    """A parsed script: its steps in order, with what each frame gets from them."""

    def __init__(self, steps: list[Step]):
        self.steps = steps
        self._next = 0

    def instants(self, frame: int) -> list[Step]:
        """The one-frame steps (keys, truth, screenshots, saves, quit) due at ``frame``, in file
        order; each is returned once (call with increasing frames)."""
        out = []
        while self._next < len(self.steps) and self.steps[self._next].frame <= frame:
            step = self.steps[self._next]
            if step.kind not in LASTING:
                out.append(step)
            self._next += 1
        return out

    def held(self, frame: int) -> tuple[set[str], bool]:
        """The movement keys held at ``frame`` and whether shift is held with any of them."""
        keys, fast = set(), False
        for s in self.steps:
            if s.kind == "hold" and s.frame <= frame < s.frame + s.frames:
                name = str(s.value)
                fast = fast or name.startswith("shift+")
                keys.add(name.removeprefix("shift+"))
        return keys, fast

    def drag(self, frame: int) -> tuple[float, float]:
        """The mouse drag (dx, dy) at ``frame``: each drag step's total spread evenly over its
        frames."""
        dx = dy = 0.0
        for s in self.steps:
            if s.kind == "drag" and s.frame <= frame < s.frame + s.frames:
                dx += s.value[0] / s.frames
                dy += s.value[1] / s.frames
        return dx, dy

    @property
    def done(self) -> bool:
        """True when every step has been handed out (lasting ones may still run)."""
        return self._next >= len(self.steps)


def parse_script(data: dict, file: str) -> Script:
    """A :class:`Script` from a parsed TOML file; SceneError (one line naming the step and the
    key) on anything else."""
    rd = TableReader(data, "", file)
    tables = rd.table_list("step", [])
    rd.finish()  # before the "no steps" check: a misspelt [[steps]] gets its "did you mean"
    if not tables:
        raise SceneError(file, "step", "a script needs at least one [[step]]")
    steps, frame = [], 0
    for i, table in enumerate(tables):
        srd = TableReader(table, f"step[{i}]", file)
        given = [k for k in KINDS if k in table]
        if len(given) != 1:
            raise srd.error(given[1] if given else "key",
                            f"a step does exactly one of {', '.join(KINDS)}; got "
                            f"{', '.join(given) if given else 'none'}")
        kind = given[0]
        start = srd.number("frame", frame, min=0, integer=True)
        if steps and start < steps[-1].frame:
            raise srd.error("frame", f"steps run in order: frame {start} comes before the previous step's "
                                     f"frame {steps[-1].frame}")
        frames = srd.number("frames", 1, min=1, integer=True) if kind in LASTING else 1
        if kind == "key":
            value = srd.string("key", choices=list(KEYMAP))
        elif kind == "hold":
            value = srd.string("hold", choices=[*MOVE_KEYS, *(f"shift+{k}" for k in MOVE_KEYS)])
        elif kind == "drag":
            value = tuple(float(v) for v in srd.vector("drag", 2))
        elif kind in ("wait_truth", "quit"):
            if not srd.boolean(kind):
                raise srd.error(kind, "must be true (leave the step out otherwise)")
            value = True
        else:
            value = srd.string(kind)
            if not value:
                raise srd.error(kind, "must name a file")
        srd.finish()
        steps.append(Step(kind, value, int(start), int(frames)))
        frame = int(start) + int(frames)
    return Script(steps)


def load_script(path) -> Script:
    """Read a script file (SceneError naming the file when it is missing or not TOML)."""
    return parse_script(read_toml_file(path), str(path))
