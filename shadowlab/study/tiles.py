"""``tiles.npz`` in a study directory (docs/contracts.md#study-directory): per scene and configuration,
the per-tile error sums of every light (:func:`shadowlab.evaluation.tiles.tile_sums`, the lights'
tiles side by side), which the verdicts' significance tests resample
(:mod:`shadowlab.analysis.significance`).

Layout: ``keys`` — a string array of ``"<scene>\\t<label>"`` (``label``: the configuration's full
spec, results.csv's ``label`` as run); ``t<i>`` — float32 (3, N) for ``keys[i]``, rows evaluated
pixels, wrong pixels, Σ|V − G|.
"""
from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np

from ..util.files import replacing

#: The file's name in a study directory.
TILES_FILE = "tiles.npz"

Tiles = dict[tuple[str, str], np.ndarray]


def write_tiles(path: Path, tiles: Tiles) -> Path:
    """Write ``tiles`` ({(scene, label): float32 (3, N)}) to ``path`` (temporary name, renamed)."""
    keys = list(tiles)
    arrays = {f"t{i}": np.asarray(tiles[k], np.float32) for i, k in enumerate(keys)}
    buffer = io.BytesIO()
    np.savez_compressed(buffer, keys=np.array([f"{s}\t{label}" for s, label in keys], dtype=str), **arrays)
    with replacing(Path(path)) as (tmp,):
        tmp.write_bytes(buffer.getvalue())
    return Path(path)


def read_tiles(study_dir: Path) -> Tiles:
    """The tiles of a study directory, {} when it has none (a study older than the file) or the
    file cannot be read: the verdicts then say their ties are exact equality only."""
    path = Path(study_dir) / TILES_FILE
    if not path.is_file():
        return {}
    try:
        with np.load(path, allow_pickle=False) as z:
            keys = [str(k).split("\t", 1) for k in z["keys"]]
            return {(s, label): z[f"t{i}"] for i, (s, label) in enumerate(keys)}
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        return {}
