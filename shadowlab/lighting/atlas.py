"""The shadow atlas's allocation: many lights' shadow maps in one square texture.

Each light's per-face resolution is chosen from its screen-space importance, the faces are packed
as square power-of-two tiles, and the lights that find no room are reported (issue 40). Pure
Python and numpy, no GL: the caller renders each tile's face into its rect (the map toolkit's ``depth_pass`` draws
an atlas's faces in their rects) and reports :attr:`AtlasPlan.overflow`.

**Resolution from importance** (:func:`requested_resolution`). A light's importance is its
screen-space importance (≥ 0; the share of the frame's unshadowed radiance it brings, computed by
the caller). Virtual shadow maps choose a page's resolution from the screen size it projects to
(Unreal Engine 5's virtual shadow maps; Olsson et al. 2014, "Efficient virtual shadow maps for
many lights"), so that a map texel covers about one screen pixel wherever the shadow is seen.
Here the light as a whole stands in for its pages: with n lights and light i's share
s_i = importance_i / Σ importance, its per-face request is

    r_i = 2^⌊log2(max_resolution · √(n · s_i))⌋, clamped to [min_resolution, max_resolution]

— a light of average importance (s_i = 1/n) asks for ``max_resolution``; the texels a light asks
for (r_i² per face) grow in proportion to its importance, the square root because texels grow as
the square of the side; rounding down to a power of two keeps tiles packable and never asks for
more than the rule's texels. The per-face resolution does not depend on the light's faces: a
point light's cube faces get the resolution a spot light of the same importance gets, at six
times the texels. All importances zero: every light counts as average.

**Packing** (:func:`pack`). Square power-of-two tiles placed largest first, each at the next free
cell of its size in Morton (Z) order — a buddy allocator / quadtree that never splits a cell it
has not filled: while the tiles come largest first, the area used is a multiple of each new
tile's area, so the tile starts on its own grid, and the tiles fill the atlas with no gap. Tiles
of total area ≤ the atlas's area therefore always fit, and none overlap.

**When the requests do not fit** (:func:`allocate`): the least important lights are halved first,
in rounds — each round walks the lights from the least important up, halving each one still
above ``min_resolution``, and the walk stops as soon as everything fits. Every light thus loses
the same number of levels, give or take one that the least important lose first, so the texels
stay near proportional to importance and a more important light never ends up with smaller
tiles than a less important one. If even every light at ``min_resolution`` does not fit, the
least important lights are dropped, one at a time, until the rest do: those go to
:attr:`AtlasPlan.overflow` (the caller reports them: they get no shadow map, never silently).
Last, room left over (a halving or a drop that freed more than needed) goes back, most important
light first, a level at a time, up to each light's request and never above a more important
light's resolution.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Tile:
    """One face of one light's map in the atlas: the ``light``'s face ``face`` (0 … faces − 1) in
    the square of side ``size`` texels with its lower-left corner at (``x``, ``y``) — texels of
    the atlas, x right, y up as GL's viewport rects."""

    light: int
    face: int
    x: int
    y: int
    size: int

    @property
    def rect(self) -> tuple[int, int, int, int]:
        """(x, y, width, height): the tile as a viewport rect."""
        return self.x, self.y, self.size, self.size


@dataclass
class AtlasPlan:
    """A shadow atlas's allocation (:func:`allocate`): the atlas's side ``size`` (texels), one
    :class:`Tile` per face of every light that got room (``tiles``, in packing order), per light
    its per-face resolution (``resolution``: the lights with tiles only), the lights that got no
    tile even at the smallest resolution (``overflow``, least important first), the texels the
    tiles cover (``texels_used``) and per light the resolution it asked for before any halving
    (``requested``: every light)."""

    size: int
    tiles: list[Tile]
    resolution: dict[int, int]
    overflow: list[int]
    texels_used: int
    requested: dict[int, int] = field(default_factory=dict)

    def tiles_of(self, light: int) -> list[Tile]:
        """The tiles of ``light``, face 0 first (empty for a light in :attr:`overflow`)."""
        return sorted((t for t in self.tiles if t.light == light), key=lambda t: t.face)

    @property
    def occupancy(self) -> float:
        """Share of the atlas's texels the tiles cover."""
        return self.texels_used / float(self.size * self.size)


def _is_power_of_two(v) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 1 and (int(v) & (int(v) - 1)) == 0


def _check(importance: dict, faces: dict, atlas_size: int, max_resolution: int, min_resolution: int) -> None:
    """ValueError (one line, naming the parameter) for input :func:`allocate` cannot plan."""
    for name, v in (("atlas_size", atlas_size), ("max_resolution", max_resolution),
                    ("min_resolution", min_resolution)):
        if not _is_power_of_two(v):
            raise ValueError(f"{name} must be a power of two (a positive integer), not {v!r}")
    if not min_resolution <= max_resolution <= atlas_size:
        raise ValueError(f"max_resolution must lie between min_resolution and atlas_size: "
                         f"{min_resolution} <= {max_resolution} <= {atlas_size} does not hold")
    if set(importance) != set(faces):
        raise ValueError(f"faces must name the lights importance names: {sorted(set(importance) ^ set(faces))} "
                         f"are in only one of them")
    for light, v in importance.items():
        if not (isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v) and v >= 0):
            raise ValueError(f"importance of light {light} must be a finite number >= 0, not {v!r}")
    for light, n in faces.items():
        if not (isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 1):
            raise ValueError(f"faces of light {light} must be a positive integer, not {n!r}")


def importance_order(importance: dict[int, float]) -> list[int]:
    """The lights, most important first; equal importance: the lower light index first (the
    order every choice of :func:`allocate` follows, so a plan is deterministic)."""
    return sorted(importance, key=lambda light: (-float(importance[light]), light))


def requested_resolution(importance: dict[int, float], max_resolution: int, min_resolution: int) -> dict[int, int]:
    """Per light the per-face resolution its importance asks for (the rule in the module's
    docstring): max_resolution · √(n · share) rounded down to a power of two, clamped to
    [``min_resolution``, ``max_resolution``]."""
    n = len(importance)
    total = float(sum(float(v) for v in importance.values()))
    out = {}
    for light, v in importance.items():
        share = float(v) / total if total > 0 else 1.0 / n
        wanted = max_resolution * math.sqrt(n * share)
        r = 2 ** math.floor(math.log2(wanted)) if wanted >= 1 else 1
        out[light] = int(min(max_resolution, max(min_resolution, r)))
    return out


def _morton_cell(index: int) -> tuple[int, int]:
    """(column, row) of cell ``index`` in Morton (Z) order: x from the even bits, y from the odd."""
    x = y = 0
    bit = 0
    while index:
        x |= (index & 1) << bit
        y |= ((index >> 1) & 1) << bit
        index >>= 2
        bit += 1
    return x, y


def pack(sizes: list[tuple[int, int, int]], atlas_size: int) -> list[Tile]:
    """Place square power-of-two tiles, given as (light, face, size), in an atlas of side
    ``atlas_size``: largest first (then in the given order), each at the next free cell of its
    size in Morton order (see the module docstring: no gaps, no overlaps). ValueError when their
    total area exceeds the atlas's."""
    order = sorted(range(len(sizes)), key=lambda i: -sizes[i][2])  # stable: ties keep the given order
    used = 0
    tiles = []
    for i in order:
        light, face, size = sizes[i]
        area = size * size
        if used + area > atlas_size * atlas_size:
            raise ValueError(f"tiles of {sum(s * s for _, _, s in sizes)} texels exceed the "
                             f"{atlas_size}x{atlas_size} atlas")
        col, row = _morton_cell(used // area)  # used is a multiple of area: tiles come largest first
        tiles.append(Tile(light, face, col * size, row * size, size))
        used += area
    return tiles


def allocate(importance: dict[int, float], faces: dict[int, int], atlas_size: int, max_resolution: int,
             min_resolution: int) -> AtlasPlan:
    """Plan one square shadow atlas of side ``atlas_size`` for the lights of ``importance``
    ({light: screen-space importance ≥ 0}) with ``faces`` ({light: faces of its map}: 6 for a
    point light's cube, 1 for a spot or directional light): each light's per-face resolution
    from its importance (:func:`requested_resolution`), halved least important first while the
    tiles do not fit, the least important lights dropped to :attr:`AtlasPlan.overflow` when even
    ``min_resolution`` tiles of all do not fit, spare room given back most important first, the
    tiles packed (:func:`pack`). The module's docstring gives the rules and their reasons. All
    sizes are powers of two with ``min_resolution`` ≤ ``max_resolution`` ≤ ``atlas_size``;
    ValueError (naming the parameter) otherwise. Deterministic: ties in importance go to the
    lower light index."""
    _check(importance, faces, atlas_size, max_resolution, min_resolution)
    capacity = atlas_size * atlas_size
    requested = requested_resolution(importance, max_resolution, min_resolution) if importance else {}
    order = importance_order(importance)  # most important first
    res = dict(requested)

    def used(lights) -> int:
        return sum(faces[light] * res[light] ** 2 for light in lights)

    # halve in rounds, least important first, until the tiles fit or all are at the minimum
    total = used(order)
    while total > capacity and any(res[light] > min_resolution for light in order):
        for light in reversed(order):
            if res[light] > min_resolution:
                total -= faces[light] * res[light] ** 2 * 3 // 4
                res[light] //= 2
                if total <= capacity:
                    break
    # even at the minimum: drop the least important lights until the rest fit
    kept = list(order)
    overflow = []
    while total > capacity:
        light = kept.pop()
        total -= faces[light] * res[light] ** 2
        overflow.append(light)
    # spare room back, most important first, a level at a time, never above a more important light
    grown = True
    while grown:
        grown = False
        for k, light in enumerate(kept):
            ceiling = requested[light] if k == 0 else min(requested[light], res[kept[k - 1]])
            extra = faces[light] * res[light] ** 2 * 3
            if res[light] * 2 <= ceiling and total + extra <= capacity:
                res[light] *= 2
                total += extra
                grown = True
    sizes = [(light, f, res[light]) for light in kept for f in range(faces[light])]
    tiles = pack(sizes, atlas_size)
    return AtlasPlan(size=atlas_size, tiles=tiles, resolution={light: res[light] for light in kept},
                     overflow=overflow, texels_used=sum(t.size * t.size for t in tiles), requested=requested)


def _light_colour(light: int) -> np.ndarray:
    """A bright colour per light index (golden-ratio hues), RGB uint8."""
    h = (light * 0.6180339887498949) % 1.0
    i, f = int(h * 6), (h * 6) % 1.0
    v, s = 0.95, 0.6
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    rgb = [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)][i % 6]
    return (np.asarray(rgb) * 255).astype(np.uint8)


def draw_plan(plan: AtlasPlan, pixels: int = 512) -> np.ndarray:
    """A picture of ``plan``: uint8 (pixels, pixels, 3), row 0 = top (the atlas's y up), each
    tile filled with its light's colour and outlined dark, unused texels black — for the docs and
    for eyeballing a plan. ``pixels`` (≤ the atlas's side keeps one pixel per texel or fewer)."""
    img = np.zeros((pixels, pixels, 3), np.uint8)
    scale = pixels / float(plan.size)
    for t in plan.tiles:
        x0, x1 = int(round(t.x * scale)), int(round((t.x + t.size) * scale))
        y0, y1 = int(round(t.y * scale)), int(round((t.y + t.size) * scale))
        rows = slice(pixels - y1, pixels - y0)  # y up in the atlas, row 0 at the top here
        img[rows, x0:x1] = _light_colour(t.light)
        if x1 - x0 >= 3 and y1 - y0 >= 3:
            dark = (_light_colour(t.light) // 3).astype(np.uint8)
            img[pixels - y1, x0:x1] = dark
            img[pixels - y0 - 1, x0:x1] = dark
            img[rows, x0] = dark
            img[rows, x1 - 1] = dark
    return img
