"""Generate the many-light scenes (issue 40): a city block grid at night and a furnished room,
every light but the moon with a ``range`` (docs/contracts.md#lights-per-type).

Run it again to reproduce the files byte for byte (numpy only; a fixed random seed; nothing
here is imported by the package)::

    python experiments/make_many_light_scenes.py [--out DIR]

Writes into ``shadowlab/scenes/`` (or ``--out``):

* ``ml_city_256.toml`` — a 3 x 3 grid of city blocks (14 m square, raised 15 cm sidewalk slabs,
  2 x 2 buildings of 4-15 m on each) with 8 m streets, at night: 96 street lamps (downward
  spot lights under the arm of a 5 m post, range 8 m) along the block edges, 159 window and shop
  lights (small point lights 0.5-0.7 m in front of the facades, range 2.5-4.5 m), and one dim
  directional moon, the only light with ambient > 0. Smaller casters: the lamp posts and arms,
  benches on the sidewalks and cars parked along the curbs. Seen from above a corner of the grid.
* ``ml_city_64.toml`` — the same city and camera, lit by 64 of those lights: the moon, every
  fourth street lamp (24) and 39 of the window lights. Only the light count differs.
* ``ml_city_walk.toml`` — the 64-light city with a camera walking down a street at eye height
  (24 frames, ``shadowlab animate``); the still camera is the first keyframe.
* ``ml_interior.toml`` — a 12 x 8 x 3.2 m room (floor, walls and a ceiling of boxes) with tables,
  chairs, shelves and a sofa, lit by 40 ranged lamps: 12 pendant point lights under shades, 8 table lamps,
  12 wall spots washing the walls, 6 shelf lights and 2 reading spots; no ambient at all.

Every light but the moon has ambient 0: the shading adds each light's ambient term, so 256
lights with the default 0.15 would wash everything out. A ranged light's colour is its
intensity at distance 1 (the 1/d² falloff), hence colours well above 1 for lamps 4-5 m up.

The counts (triangles, lights) are printed; they are the figures in docs/hard-cases.md.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
SEED = 40

# --------------------------------------------------------------------------- TOML writing


def num(x: float) -> str:
    """A float rounded to millimetres, written the same way every run."""
    v = round(float(x), 3)
    return repr(v + 0.0)  # + 0.0: no "-0.0"


def vec(v) -> str:
    return "[" + ", ".join(num(x) for x in v) + "]"


class Writer:
    """Collects a scene file's text: header, camera, lights, objects, animation."""

    def __init__(self):
        self.lines: list[str] = []
        self.triangles = 0
        self.lights = 0

    def raw(self, text: str) -> None:
        self.lines.append(text.rstrip("\n"))

    def light(self, type_: str, **keys) -> None:
        self.lights += 1
        out = ["", "[[lights]]", f'type = "{type_}"']
        for k, v in keys.items():
            out.append(f"{k} = {vec(v) if isinstance(v, (list, tuple, np.ndarray)) else num(v)}")
        self.lines += out

    def box(self, name: str, size, centre, *, diffuse=None, rotate_y: float = 0.0, casts: bool = True,
            specular=None, shininess=None) -> None:
        self.triangles += 12
        out = ["", "[[objects]]", f'name = "{name}"', 'mesh = "box"', f"size = {vec(size)}",
               f"translate = {vec(centre)}"]
        if rotate_y:
            out.append(f"rotate = {vec([0.0, rotate_y, 0.0])}")
        if not casts:
            out.append("casts = false")
        if diffuse is not None or specular is not None:
            out.append("[objects.material]")
            if diffuse is not None:
                out.append(f"diffuse = {vec(diffuse)}")
            if specular is not None:
                out.append(f"specular = {vec(specular)}")
            if shininess is not None:
                out.append(f"shininess = {num(shininess)}")
        self.lines += out

    def plane(self, name: str, size, *, diffuse) -> None:
        self.triangles += 2
        self.lines += ["", "[[objects]]", f'name = "{name}"', 'mesh = "plane"', f"size = {vec(size)}",
                       "[objects.material]", f"diffuse = {vec(diffuse)}"]

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


# --------------------------------------------------------------------------- the city

BLOCKS = 3              # blocks per side
BLOCK = 14.0            # block (sidewalk slab) side, m
STREET = 8.0            # street width between slabs, m
PITCH = BLOCK + STREET
CURB = 0.15             # sidewalk slab height
POST_HEIGHT = 5.0
ARM = 0.8               # the arm reaches this far over the street
LAMP_RANGE = 8.0

WARM = np.array([1.0, 0.72, 0.42])    # sodium / incandescent
NEUTRAL = np.array([1.0, 0.9, 0.75])
COOL = np.array([0.62, 0.78, 1.0])    # LED / fluorescent / TV
MOON = [0.5, -1.0, 0.35]


def block_centres() -> list[np.ndarray]:
    """Centres (x, z) of the blocks, row by row."""
    offsets = (np.arange(BLOCKS) - (BLOCKS - 1) / 2) * PITCH
    return [np.array([x, z]) for z in offsets for x in offsets]


N_LAMPS = 96


def lamp_slots() -> list[tuple[np.ndarray, np.ndarray]]:
    """Every street-lamp slot: (post foot (x, z), unit outward normal (x, z) of its block edge),
    three per block edge (108), 0.4 m inside the slab's edge; posts stand at :data:`N_LAMPS` of
    them (:func:`post_slots`), benches and cars go beside any of them."""
    slots = []
    for c in block_centres():
        for n in (np.array([1.0, 0.0]), np.array([0.0, 1.0]), np.array([-1.0, 0.0]), np.array([0.0, -1.0])):
            t = np.array([-n[1], n[0]])
            for s in (-4.5, 0.0, 4.5):
                slots.append((c + n * (BLOCK / 2 - 0.4) + t * s, n))
    return slots


def post_slots() -> list[tuple[np.ndarray, np.ndarray]]:
    """The :data:`N_LAMPS` slots with a lamp post (a seeded choice of its own, in slot order)."""
    slots = lamp_slots()
    keep = np.sort(np.random.default_rng(SEED + 3).choice(len(slots), N_LAMPS, replace=False))
    return [slots[k] for k in keep]


def city_geometry(w: Writer, rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray, float, float]]:
    """The ground, slabs, buildings, posts, benches and cars into ``w``; returns the facades the
    window lights may sit on: (point on the facade's centre line at the foot (x, z), outward
    unit normal (x, z), half width, height)."""
    extent = BLOCKS * PITCH + STREET
    w.plane("ground", [extent + 20.0, extent + 20.0], diffuse=[0.3, 0.3, 0.32])  # asphalt
    facades = []
    for bi, c in enumerate(block_centres()):
        w.box(f"block{bi}_sidewalk", [BLOCK, CURB, BLOCK], [c[0], CURB / 2, c[1]], diffuse=[0.5, 0.49, 0.47])
        for li, (sx, sz) in enumerate(((-1, -1), (1, -1), (-1, 1), (1, 1))):
            lot = c + 3.0 * np.array([sx, sz])
            size = rng.uniform(4.0, 5.0, 2)   # at most 5.5 m from the block's centre: a 1.5 m sidewalk
            height = float(rng.choice([4.0, 5.0, 6.0, 8.0, 10.0, 12.0, 15.0]))
            shade = rng.uniform(0.35, 0.6)
            tint = np.array([1.0, 0.95, 0.88]) if rng.random() < 0.5 else np.array([0.9, 0.93, 1.0])
            w.box(f"block{bi}_building{li}", [size[0], height, size[1]], [lot[0], CURB + height / 2, lot[1]],
                  diffuse=shade * tint)
            # the two facades that face streets (outward from the block's centre)
            facades.append((lot + np.array([sx * size[0] / 2, 0.0]), np.array([float(sx), 0.0]), size[1] / 2, height))
            facades.append((lot + np.array([0.0, sz * size[1] / 2]), np.array([0.0, float(sz)]), size[0] / 2, height))
    for pi, (foot, n) in enumerate(post_slots()):
        w.box(f"post{pi}", [0.12, POST_HEIGHT, 0.12], [foot[0], CURB + POST_HEIGHT / 2, foot[1]],
              diffuse=[0.15, 0.15, 0.16])
        arm_mid = foot + n * (ARM / 2)
        size = [ARM + 0.12, 0.08, 0.12] if n[0] else [0.12, 0.08, ARM + 0.12]
        w.box(f"arm{pi}", size, [arm_mid[0], CURB + POST_HEIGHT - 0.04, arm_mid[1]], diffuse=[0.15, 0.15, 0.16])
    # benches: on the sidewalks, between the lamp slots, facing the street
    slots = lamp_slots()
    for bi, k in enumerate(sorted(rng.choice(len(slots), 18, replace=False))):
        foot, n = slots[k]
        t = np.array([-n[1], n[0]])
        p = foot + t * 2.2 - n * 0.4
        along = 0.0 if n[1] else 90.0
        w.box(f"bench{bi}_seat", [1.6, 0.45, 0.45], [p[0], CURB + 0.225, p[1]], rotate_y=along,
              diffuse=[0.45, 0.3, 0.18])
        back = p - n * 0.2
        w.box(f"bench{bi}_back", [1.6, 0.5, 0.06], [back[0], CURB + 0.7, back[1]], rotate_y=along,
              diffuse=[0.45, 0.3, 0.18])
    # cars parked along the curbs (body and cabin), in the streets between the blocks
    colours = [[0.6, 0.08, 0.06], [0.1, 0.18, 0.45], [0.75, 0.75, 0.72], [0.12, 0.12, 0.12], [0.5, 0.45, 0.1],
               [0.2, 0.35, 0.25]]
    for ci, k in enumerate(sorted(rng.choice(len(slots), 30, replace=False))):
        foot, n = slots[k]
        t = np.array([-n[1], n[0]])
        p = foot + n * (0.4 + 1.1) + t * rng.uniform(-1.5, 1.5)   # 1.1 m off the curb: the car's half width
        along = 90.0 if n[0] else 0.0   # the car's length (x of the box) along the street
        colour = colours[int(rng.integers(len(colours)))]
        w.box(f"car{ci}_body", [4.2, 0.75, 1.8], [p[0], 0.2 + 0.375, p[1]], rotate_y=along, diffuse=colour,
              specular=[0.6, 0.6, 0.6], shininess=64.0)
        w.box(f"car{ci}_cabin", [2.2, 0.6, 1.6], [p[0], 0.95 + 0.3, p[1]], rotate_y=along,
              diffuse=[0.1, 0.1, 0.12], specular=[0.6, 0.6, 0.6], shininess=64.0)
    return facades


def city_lights(rng: np.random.Generator, facades) -> tuple[list[dict], list[dict]]:
    """The 96 street lamps and 159 window and shop lights of the full city (each a dict of
    ``[[lights]]`` keys); the moon is written separately."""
    lamps = []   # one under each post's arm
    for foot, n in post_slots():
        p = foot + n * (ARM - 0.05)
        direction = [0.25 * n[0], -1.0, 0.25 * n[1]]   # down, tilted towards the street
        colour = (WARM if rng.random() < 0.6 else NEUTRAL) * rng.uniform(30.0, 40.0)
        lamps.append(dict(position=[p[0], CURB + POST_HEIGHT - 0.12, p[1]], direction=direction, alpha=110.0,
                          beta=70.0, color=colour, ambient=0.0, range=LAMP_RANGE))
    windows = []
    order = rng.permutation(len(facades))
    k = 0
    while len(windows) < 159:
        foot, n, half, height = facades[order[k % len(facades)]]
        k += 1
        t = np.array([-n[1], n[0]])
        shop = rng.random() < 0.35
        y = CURB + (rng.uniform(1.6, 2.4) if shop else rng.uniform(3.5, max(3.6, height - 1.0)))
        p = foot + n * rng.uniform(0.5, 0.7) + t * rng.uniform(-0.8, 0.8) * half
        base = WARM if rng.random() < 0.5 else (NEUTRAL if rng.random() < 0.5 else COOL)
        colour = base * (rng.uniform(2.5, 4.0) if shop else rng.uniform(1.2, 2.2))
        windows.append(dict(position=[p[0], y, p[1]], color=colour, ambient=0.0,
                            range=rng.uniform(3.5, 4.5) if shop else rng.uniform(2.5, 3.5)))
    return lamps, windows


CITY_HEADER = """\
# Many lights (issue 40): a city at night lit by {n} lights, {what}: a 3 x 3 grid of 14 m
# blocks (raised sidewalk slabs, 2 x 2 buildings of 4-15 m on each) between 8 m streets, with
# lamp posts, benches and parked cars as small casters. Street lamps are downward spot lights
# under the arms of 5 m posts (range 8 m); window and shop lights are small point lights just in
# front of the facades (range 2.5-4.5 m); one dim moon (directional) is the only light with
# ambient > 0. Every ranged light reaches only its pool (its evaluated pixels), and the pools
# overlap along the streets: what shadow budgets and light selection have to share out.
# Generated by experiments/make_many_light_scenes.py (seed {seed}): edit that, not this file.
family = "many lights"
name = "{name}"
"""


def city(name: str, n_lights: int, camera: str, animation: str = "", what: str = "") -> tuple[str, Writer]:
    """One city scene file: the shared geometry (same seed: the same city every time), the
    moon, and ``n_lights`` − 1 ranged lights (all of them, or every fourth lamp and the first
    window lights)."""
    rng = np.random.default_rng(SEED)
    w = Writer()
    w.raw(CITY_HEADER.format(n=n_lights, name=name, seed=SEED, what=what))
    w.raw(camera)
    lights_rng = np.random.default_rng(SEED + 1)
    body = Writer()
    facades = city_geometry(body, rng)
    lamps, windows = city_lights(lights_rng, facades)
    if n_lights == 256:
        chosen = lamps + windows
    else:
        n_lamps = len(lamps) * n_lights // 256     # 24 of 64
        chosen = lamps[::len(lamps) // n_lamps][:n_lamps] + windows[: n_lights - 1 - n_lamps]
    w.light("directional", direction=MOON, color=[0.03, 0.035, 0.05], ambient=0.025)
    for lt in chosen:
        w.light("spot" if "direction" in lt else "point", **lt)
    w.lines += body.lines
    w.triangles += body.triangles
    if animation:
        w.raw("\n" + animation)
    return w.text(), w


CITY_CAMERA = """
[camera]
eye = [-34.0, 34.0, 30.0]
target = [2.0, 0.0, -4.0]
fov_y = 50.0
"""

# Walk east along the street between the first and second rows of blocks (z = -11), from the
# west edge of the city to past its middle, at eye height, looking ahead and a little down.
WALK_Z = -PITCH / 2
WALK_CAMERA = f"""
[camera]
eye = [-36.0, 1.7, {num(WALK_Z - 1.5)}]
target = [-20.0, 1.0, {num(WALK_Z - 0.5)}]
fov_y = 60.0
"""

WALK_ANIMATION = f"""\
[animation]
frames = 24
[[animation.camera]]          # walking east down the street, then turning a little to the left
t = 0.0
eye = [-36.0, 1.7, {num(WALK_Z - 1.5)}]
target = [-20.0, 1.0, {num(WALK_Z - 0.5)}]
[[animation.camera]]
t = 0.7
eye = [-8.0, 1.7, {num(WALK_Z - 1.5)}]
target = [8.0, 1.0, {num(WALK_Z - 0.5)}]
[[animation.camera]]
t = 1.0
eye = [4.0, 1.7, {num(WALK_Z - 1.0)}]
target = [18.0, 1.0, {num(WALK_Z + 4.0)}]"""


# --------------------------------------------------------------------------- the interior

ROOM = (12.0, 3.2, 8.0)   # x, y (height), z; the floor at y = 0, centred on x and z
WALL = 0.2

INTERIOR_HEADER = """\
# Many lights (issue 40): a furnished room at night lit by 40 lamps, all ranged and none with
# ambient: 12 pendant point lights (under shades 12 cm above them), 8 table lamps, 12 wall spots washing the walls, 6 shelf
# lights and 2 reading spots, over tables, chairs, shelves and a sofa in a 12 x 8 x 3.2 m room
# (walls and ceiling are boxes; the camera stands inside, in one corner, at eye height). Small ranges
# (1.5-3.6 m) in a closed room: every pixel sees a handful of lights, each light a small part of
# the room, and furniture casts overlapping shadows from lights of different heights.
# Generated by experiments/make_many_light_scenes.py (seed {seed}): edit that, not this file.
family = "many lights"
name = "ml_interior"

[camera]
eye = [5.3, 1.6, 3.6]
target = [-2.5, 0.4, -2.4]
fov_y = 60.0
"""


def furniture(w: Writer, rng: np.random.Generator) -> dict:
    """Tables, chairs, shelves and a sofa into ``w``; returns where the lamps go."""
    wood = [0.5, 0.34, 0.2]
    spots = {"tables": [], "shelves": [], "sofa": None}
    tables = [(-3.5, -1.5), (-3.5, 1.8), (1.0, -1.5), (1.0, 1.8)]
    for ti, (x, z) in enumerate(tables):
        top_y = 0.75
        w.box(f"table{ti}_top", [1.6, 0.05, 0.9], [x, top_y - 0.025, z], diffuse=wood, specular=[0.3, 0.3, 0.3])
        for li, (dx, dz) in enumerate(((-0.72, -0.38), (0.72, -0.38), (-0.72, 0.38), (0.72, 0.38))):
            w.box(f"table{ti}_leg{li}", [0.06, top_y - 0.05, 0.06], [x + dx, (top_y - 0.05) / 2, z + dz], diffuse=wood)
        spots["tables"].append((x, top_y, z))
        for ci, side in enumerate((-1, 1)):   # a chair at each long side, pulled out by a random amount
            cz = z + side * rng.uniform(0.7, 0.85)
            cx = x + rng.uniform(-0.35, 0.35)
            w.box(f"table{ti}_chair{ci}_seat", [0.45, 0.05, 0.45], [cx, 0.45, cz], diffuse=[0.3, 0.22, 0.15])
            back_z = cz + side * 0.2
            w.box(f"table{ti}_chair{ci}_back", [0.45, 0.5, 0.05], [cx, 0.72, back_z], diffuse=[0.3, 0.22, 0.15])
            for li, (dx, dz) in enumerate(((-0.2, -0.2), (0.2, -0.2), (-0.2, 0.2), (0.2, 0.2))):
                w.box(f"table{ti}_chair{ci}_leg{li}", [0.04, 0.425, 0.04], [cx + dx, 0.2125, cz + dz],
                      diffuse=[0.3, 0.22, 0.15])
    # shelves along the back wall (z = -4): two sides, a top and four boards each
    back = -ROOM[2] / 2 + WALL / 2
    for si, x in enumerate((-4.0, -1.0, 2.5)):
        z = back + 0.2
        for side in (-1, 1):
            w.box(f"shelf{si}_side{side + 1}", [0.04, 2.2, 0.4], [x + side * 0.6, 1.1, z], diffuse=wood)
        for bi, y in enumerate((0.1, 0.6, 1.1, 1.6, 2.18)):
            w.box(f"shelf{si}_board{bi}", [1.16, 0.04, 0.4], [x, y, z], diffuse=wood)
        for bi, y in enumerate((0.6, 1.6)):   # some books: boxes on two boards
            n_books = int(rng.integers(3, 6))
            xs = np.sort(rng.uniform(-0.5, 0.45, n_books))
            for k, bx in enumerate(xs):
                h = rng.uniform(0.22, 0.32)
                w.box(f"shelf{si}_book{bi}_{k}", [0.05, h, 0.25], [x + bx, y + 0.02 + h / 2, z],
                      diffuse=rng.uniform(0.2, 0.7, 3))
        spots["shelves"] += [(x, 1.35, z + 0.02), (x, 0.85, z + 0.02)]
    # a sofa against the right wall (x = +6)
    sx = ROOM[0] / 2 - WALL / 2 - 0.5
    fabric = [0.35, 0.4, 0.5]
    w.box("sofa_seat", [0.9, 0.45, 2.2], [sx, 0.225, 1.0], diffuse=fabric)
    w.box("sofa_back", [0.2, 0.5, 2.2], [sx + 0.35, 0.7, 1.0], diffuse=fabric)
    for k, dz in enumerate((-1.2, 1.2)):
        w.box(f"sofa_arm{k}", [0.9, 0.6, 0.2], [sx, 0.3, 1.0 + dz], diffuse=fabric)
    w.box("side_table", [0.5, 0.55, 0.5], [sx, 0.275, -0.8], diffuse=wood)
    spots["sofa"] = (sx, 1.0)
    return spots


def interior() -> tuple[str, Writer]:
    """The room scene file."""
    rng = np.random.default_rng(SEED + 2)
    w = Writer()
    w.raw(INTERIOR_HEADER.format(seed=SEED + 2))
    X, H, Z = ROOM
    body = Writer()
    body.plane("floor", [X + 2 * WALL, Z + 2 * WALL], diffuse=[0.55, 0.45, 0.35])
    body.box("ceiling", [X + 2 * WALL, WALL, Z + 2 * WALL], [0.0, H + WALL / 2, 0.0], diffuse=[0.85, 0.85, 0.82])
    for name, size, centre in (("wall_back", [X, H, WALL], [0.0, H / 2, -Z / 2 - WALL / 2]),
                               ("wall_front", [X, H, WALL], [0.0, H / 2, Z / 2 + WALL / 2]),
                               ("wall_left", [WALL, H, Z + 2 * WALL], [-X / 2 - WALL / 2, H / 2, 0.0]),
                               ("wall_right", [WALL, H, Z + 2 * WALL], [X / 2 + WALL / 2, H / 2, 0.0])):
        body.box(name, size, centre, diffuse=[0.78, 0.74, 0.66])
    spots = furniture(body, rng)
    lights = []
    # pendant lights: a 4 x 3 grid hanging 0.8 m under the ceiling, each under a shade on a cord
    for k, x in enumerate((-4.5, -1.5, 1.5, 4.5)):
        for m, z in enumerate((-2.6, 0.0, 2.6)):
            y = H - 0.8
            lights.append(("point", dict(position=[x, y, z], color=NEUTRAL * rng.uniform(3.5, 4.5),
                                         ambient=0.0, range=3.6)))
            body.box(f"pendant{k}{m}_shade", [0.5, 0.04, 0.5], [x, y + 0.12, z], diffuse=[0.2, 0.2, 0.2])
            body.box(f"pendant{k}{m}_cord", [0.02, 0.66, 0.02], [x, y + 0.14 + 0.33, z], diffuse=[0.1, 0.1, 0.1])
    # table lamps: two per table, 0.45 m over the top
    for (x, y, z) in spots["tables"]:
        for dx in (-0.45, 0.45):
            lights.append(("point", dict(position=[x + dx, y + 0.45, z], color=WARM * rng.uniform(0.6, 0.9),
                                         ambient=0.0, range=2.2)))
    # wall washers: spots 0.35 m out from the left, right and front walls, 2.7 m up, aimed down the wall
    washers = [(-X / 2 + 0.35, z, [1.0, 0.0]) for z in (-2.4, 0.0, 2.4)] + \
              [(X / 2 - 0.35, z, [-1.0, 0.0]) for z in (-2.4, 2.4)] + \
              [(x, Z / 2 - 0.35, [0.0, -1.0]) for x in (-4.5, -1.5, 1.5, 4.5)] + \
              [(x, -Z / 2 + 0.35, [0.0, 1.0]) for x in (-5.2, 0.8, 4.5)]
    for x, z, n in washers:
        lights.append(("spot", dict(position=[x, H - 0.5, z], direction=[-0.35 * n[0], -1.0, -0.35 * n[1]],
                                    alpha=70.0, beta=40.0, color=WARM * rng.uniform(2.5, 3.5), ambient=0.0,
                                    range=3.5)))
    # shelf lights: small points at the front of the boards
    for (x, y, z) in spots["shelves"]:
        lights.append(("point", dict(position=[x, y, z + 0.3], color=COOL * rng.uniform(0.3, 0.45), ambient=0.0,
                                     range=1.5)))
    # reading spots over the sofa
    sx, sz = spots["sofa"]
    for dz in (-0.6, 0.6):
        lights.append(("spot", dict(position=[sx - 0.6, 2.2, sz + dz], direction=[0.2, -1.0, 0.0], alpha=60.0,
                                    beta=30.0, color=WARM * rng.uniform(1.5, 2.0), ambient=0.0, range=3.0)))
    for type_, keys in lights:
        w.light(type_, **keys)
    w.lines += body.lines
    w.triangles += body.triangles
    return w.text(), w


# --------------------------------------------------------------------------- main

def scenes() -> dict[str, tuple[str, Writer]]:
    """Every generated file: name → (text, writer with its counts)."""
    return {
        "ml_city_64": city("ml_city_64", 64, CITY_CAMERA,
                           what="the moon, 24 street lamps and 39 window and shop lights"),
        "ml_city_256": city("ml_city_256", 256, CITY_CAMERA,
                            what="the moon, 96 street lamps and 159 window and shop lights"),
        "ml_city_walk": city("ml_city_walk", 64, WALK_CAMERA, WALK_ANIMATION,
                             what="as ml_city_64, with a camera walking down a street (24 frames)"),
        "ml_interior": interior(),
    }


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "shadowlab" / "scenes", help="folder to write into")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for name, (text, w) in scenes().items():
        (args.out / f"{name}.toml").write_text(text, encoding="utf-8")
        print(f"{name}: {w.lights} lights, {w.triangles} triangles")


if __name__ == "__main__":
    main()
