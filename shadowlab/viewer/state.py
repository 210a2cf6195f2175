"""The viewer's state, with no window and no GL: the flying camera, which configuration and which
view are shown, the key bindings (as data: the HUD, the docs' keys table and the tests read the
same tables) and the clock that says when the camera has been still long enough for the truth.

Everything here is a function of the inputs it is given — key presses, held keys, mouse drags
and the time step — so a ``--script`` run, which gives a fixed time step (:data:`SCRIPT_DT`),
is deterministic, and the tests drive it without a display.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..scene.model import Camera

#: The views, in the order ``v`` cycles through them: the configuration's shaded image, the
#: ray-traced truth's, the error map against the truth (the compare pages' colours), the texel
#: footprint (map techniques) and the first light's visibility image.
VIEWS = ("shaded", "truth", "error", "footprint", "visibility")

#: Key (as the window names it; ``shift+`` when shift is held) → action on a press. Held
#: movement keys are :data:`MOVE_KEYS`. The order is the keys table's on docs/your-scenes.md.
KEYMAP = {
    "tab": "next_config",
    "shift+tab": "previous_config",
    **{str(n): f"config_{n}" for n in range(1, 10)},
    "v": "next_view",
    "f1": "view_shaded",
    "f2": "view_truth",
    "f3": "view_error",
    "f4": "view_footprint",
    "f5": "view_visibility",
    "h": "toggle_hud",
    "r": "truth_now",
    "p": "screenshot",
    "x": "save_view",
    "backspace": "reset_camera",
    "escape": "quit",
}

#: What each action does, one line each (the ``--help`` epilogue and the docs' keys table).
ACTION_HELP = {
    "next_config": "next configuration (the -t specs, in order)",
    "previous_config": "previous configuration",
    "config_n": "configuration n (1-9)",
    "next_view": "next view: shaded, truth, error, footprint, visibility",
    "view_shaded": "the configuration's shaded image",
    "view_truth": "the ray-traced truth's shaded image",
    "view_error": "the error map against the truth (false shadow orange, false lit blue)",
    "view_footprint": "the texel footprint (map techniques)",
    "view_visibility": "the first light's visibility image",
    "toggle_hud": "HUD on / off",
    "truth_now": "compute the truth now (it is computed anyway once the camera is still)",
    "screenshot": "save a screenshot of the window (PNG)",
    "save_view": "save the current view as a scene file (TOML) that compare and study read",
    "reset_camera": "back to the scene's camera",
    "quit": "quit",
}

#: Held key → (axis, sign) of the fly motion: forward along the view direction, right across
#: it, up along the camera's up vector.
MOVE_KEYS = {"w": ("forward", 1.0), "s": ("forward", -1.0), "d": ("right", 1.0), "a": ("right", -1.0),
             "e": ("up", 1.0), "q": ("up", -1.0)}

#: Flying speed in scene diagonals (:meth:`shadowlab.scene.model.Scene.extent`) per second, and
#: the factor shift multiplies it by: a scene crosses in about ten seconds, whatever its units.
SPEED_PER_EXTENT = 0.1
FAST = 5.0
#: Degrees of turn per pixel of mouse drag (yaw and pitch).
DEGREES_PER_PIXEL = 0.15
#: The pitch limit, degrees from the up vector: a camera looking along its up vector has no
#: defined right vector (and a scene file refuses it: shadowlab.scene.reading).
PITCH_MARGIN = 1.0
#: Seconds the camera must be still before the truth is computed for it (tracing takes from tens
#: of milliseconds to seconds; doing it while the camera moves would stall every frame).
STILL_SECONDS = 0.3
#: The time step of a ``--script`` run, seconds per frame: motion and the stillness clock then
#: depend on frame counts, never on how fast the machine renders.
SCRIPT_DT = 1.0 / 30.0


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _rotate(v: np.ndarray, axis: np.ndarray, degrees: float) -> np.ndarray:
    """``v`` turned by ``degrees`` about the unit ``axis`` (Rodrigues' formula)."""
    a = np.radians(degrees)
    return v * np.cos(a) + np.cross(axis, v) * np.sin(a) + axis * np.dot(axis, v) * (1.0 - np.cos(a))


@dataclass
class FlyCamera:
    """A camera that flies: ``eye`` and ``target`` (float64 (3,)) moved and turned by the fly
    maths, the rest (up vector, vertical field of view, near and far — None where the scene file
    leaves them to be fitted) as the scene's camera has them.

    The target is kept, not recomputed from angles, so an unmoved camera is the scene's camera
    bit for bit (the viewer's first frame is compare's), and a turn keeps the eye-target distance.
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    fov_y: float
    near: float | None = None
    far: float | None = None

    @classmethod
    def of(cls, camera: Camera) -> "FlyCamera":
        """The flying camera starting at ``camera`` (a scene file's, near and far as written)."""
        return cls(np.array(camera.eye, np.float64), np.array(camera.target, np.float64),
                   np.array(camera.up, np.float64), float(camera.fov_y), camera.near, camera.far)

    def camera(self) -> Camera:
        """The scene camera it stands for now."""
        return Camera(self.eye.copy(), self.target.copy(), self.up.copy(), self.fov_y, self.near, self.far)

    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit forward (eye → target), right (forward × up) and the unit up vector."""
        forward = _unit(self.target - self.eye)
        up = _unit(self.up)
        return forward, _unit(np.cross(forward, up)), up

    def move(self, forward: float, right: float, up: float) -> None:
        """Translate eye and target together by ``forward`` along the view direction, ``right``
        across it and ``up`` along the up vector (world units)."""
        f, r, u = self.axes()
        step = forward * f + right * r + up * u
        self.eye = self.eye + step
        self.target = self.target + step

    def look(self, yaw: float, pitch: float) -> None:
        """Turn about the eye: ``yaw`` degrees about the up vector (positive turns right),
        ``pitch`` degrees about the right vector (positive looks up), the pitch clamped to
        :data:`PITCH_MARGIN` degrees short of the up vector either way. The eye stays put and
        the target keeps its distance."""
        f, r, u = self.axes()
        distance = float(np.linalg.norm(self.target - self.eye))
        f = _rotate(f, u, -yaw)
        # the angle between forward and up, kept inside [margin, 180 - margin]
        angle = float(np.degrees(np.arccos(np.clip(np.dot(f, u), -1.0, 1.0))))
        pitch = float(np.clip(pitch, angle - (180.0 - PITCH_MARGIN), angle - PITCH_MARGIN))
        r = _unit(np.cross(f, u))
        f = _unit(_rotate(f, r, pitch))
        self.target = self.eye + distance * f


@dataclass
class ViewState:
    """What the viewer shows and where it stands: the configurations (spec strings) and the one
    shown, the view, the HUD switch, the flying camera and its start, the clock.

    ``camera_version`` counts camera changes (the renderer keys its caches by it);
    ``still_since`` is the clock time of the last change, from which :meth:`truth_due` says when
    the truth should be computed. ``speed`` is the flying speed in world units per second."""

    specs: list[str]
    start: Camera
    speed: float
    config: int = 0
    view: str = "shaded"
    hud: bool = True
    clock: float = 0.0
    camera_version: int = 0
    still_since: float = 0.0
    fly: FlyCamera = field(init=False)

    def __post_init__(self):
        if not self.specs:
            raise ValueError("the viewer needs at least one configuration")
        self.fly = FlyCamera.of(self.start)

    @property
    def spec(self) -> str:
        """The configuration shown."""
        return self.specs[self.config]

    def press(self, key: str) -> list[str]:
        """Apply the key ``key`` (:data:`KEYMAP`'s names); return the effects the window must
        carry out, of ``screenshot``, ``save_view``, ``truth_now``, ``quit`` (none for a key
        without a binding)."""
        action = KEYMAP.get(key)
        if action is None:
            return []
        n = len(self.specs)
        if action == "next_config":
            self.config = (self.config + 1) % n
        elif action == "previous_config":
            self.config = (self.config - 1) % n
        elif action.startswith("config_"):
            i = int(action[len("config_"):]) - 1
            if i < n:
                self.config = i
        elif action == "next_view":
            self.view = VIEWS[(VIEWS.index(self.view) + 1) % len(VIEWS)]
        elif action.startswith("view_"):
            self.view = action[len("view_"):]
        elif action == "toggle_hud":
            self.hud = not self.hud
        elif action == "reset_camera":
            self.fly = FlyCamera.of(self.start)
            self._moved()
        else:
            return [action]
        return []

    def _moved(self) -> None:
        self.camera_version += 1
        self.still_since = self.clock

    def step(self, dt: float, held: set[str] = frozenset(), drag: tuple[float, float] = (0.0, 0.0),
             fast: bool = False) -> bool:
        """Advance the clock by ``dt`` seconds, flying with the ``held`` movement keys
        (:data:`MOVE_KEYS`; ``fast``: shift, :data:`FAST` times the speed) and turning by the
        mouse ``drag`` (dx, dy) in pixels since the last step (right and down positive, as
        windows report them). True when the camera moved."""
        self.clock += dt
        motion = {"forward": 0.0, "right": 0.0, "up": 0.0}
        for key in held:
            if key in MOVE_KEYS:
                axis, sign = MOVE_KEYS[key]
                motion[axis] += sign
        moved = False
        if any(motion.values()):
            d = self.speed * (FAST if fast else 1.0) * dt
            self.fly.move(d * motion["forward"], d * motion["right"], d * motion["up"])
            moved = True
        dx, dy = drag
        if dx or dy:
            # dragging right turns right; dragging down looks down
            self.fly.look(DEGREES_PER_PIXEL * dx, -DEGREES_PER_PIXEL * dy)
            moved = True
        if moved:
            self._moved()
        return moved

    def truth_due(self) -> bool:
        """Whether the camera has been still for :data:`STILL_SECONDS` (the truth of a camera
        is computed once; the renderer knows whether it has it)."""
        # a nanosecond's slack: nine script steps of 1/30 s sum to a hair under 0.3 s
        return self.clock - self.still_since >= STILL_SECONDS - 1e-9


def default_speed(extent: float) -> float:
    """The flying speed for a scene whose diagonal is ``extent``, world units per second."""
    return SPEED_PER_EXTENT * float(extent)
