"""Suites (docs/contracts.md#study-directory): which scenes, which technique configurations, at what size and how often.

A suite is a TOML file — shipped ones live in ``shadowlab/suites/`` and are named by their stem
(``quick``), any other argument is a path::

    name = "hard_shadows"
    description = "..."            # optional
    size = [800, 600]
    repeat = 5                     # timed runs per configuration (timing phase)
    warmup = 1                     # optional, untimed runs before them
    pass_timing = false            # optional: also pass_<name>_ms columns
    scenes = ["box_on_plane", "sm_grazing", "path/to/scene.toml"]
    techniques = ["shadow_volume", "shadow_map:variant=slope", "planar"]

    [[sweeps]]                     # optional: a grid over one technique's parameters
    technique = "shadow_map"
    resolution = [256, 512, 1024]  # a list is swept; a single value is held fixed
    variant = ["constant", "slope"]
    scenes = ["sm_grazing"]        # optional: only these scenes of the suite (default: all)

Everything is checked when the suite is loaded, before any rendering: unknown keys, unknown
scenes, unknown techniques or parameters and bad values raise :class:`SuiteError` naming the
file and the entry. Scene files are resolved and parsed as TOML here; their objects and meshes
are built by the runs themselves, so a mesh that cannot be loaded is a failed run, recorded with
its error, not a refused suite.
"""
from __future__ import annotations

import itertools
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from ..evaluation.scene_metric import judged_columns
from ..techniques import TechniqueError, from_spec
from ..techniques.base import format_value
from ..techniques.rays.raytrace import RayTraced
from ..util.sizes import COMPARE_SIZE
from ..util.validation import SceneError, TableReader, did_you_mean
from ..analysis.aggregate import TUNED_MARK


class SuiteError(ValueError):
    """A suite file is malformed or names an unknown scene, technique or parameter."""


@dataclass(frozen=True)
class SceneEntry:
    """One scene of a suite: its name (the file stem), file, hard-case family (its file's
    ``family`` key) and the types of its lights (read from the file's ``[[lights]]`` tables, for
    the plan-time check that every configuration renders for them)."""

    name: str
    path: Path
    family: str
    light_types: tuple[str, ...] = ()
    #: The metrics column the scene exists for (its file's ``metric`` key), None when it has none.
    metric: str | None = None
    #: A warning about the entry for the study's log, or None: the family guessed from the name
    #: because the file declares none (:func:`shadowlab.scene.family_from_name`).
    note: str | None = None


@dataclass(frozen=True)
class TunedEntry:
    """A ``[[tuned]]`` table: the configuration ``spec`` (canonical; ``written`` as the suite
    wrote it) is run at its defaults and, on each of its scenes, at its optimum for ``objective``
    over ``params`` (``shadowlab tune``'s routes, ``budget`` renders for the search route).
    ``scenes``: the scenes it is limited to (None: all)."""

    spec: str
    written: str
    params: tuple[str, ...]
    objective: str
    budget: int
    scenes: tuple[str, ...] | None = None

    @property
    def name(self) -> str:
        """The tuned configurations' name in results.csv's ``config`` column."""
        return f"{self.written}{TUNED_MARK}{'+'.join(p.split('=')[0] for p in self.params) or 'bias'}]"

    def applies_to(self, scene: str) -> bool:
        """Whether the entry runs on ``scene``."""
        return self.scenes is None or scene in self.scenes


@dataclass
class Suite:
    """A validated suite. ``configurations`` maps each scene name to the canonical technique
    specs (``Technique.spec()``) to run on it, in suite order, without duplicates."""

    name: str
    description: str
    size: tuple[int, int]
    repeat: int
    warmup: int
    pass_timing: bool
    scenes: list[SceneEntry]
    configurations: dict[str, list[str]]
    truth: str = field(default_factory=lambda: RayTraced().spec())
    file: str = "<suite>"
    #: canonical spec → the configuration as the suite writes it (``"shadow_map:variant=slope"``,
    #: a sweep's ``"shadow_map:resolution=256"``): a name that survives a change of defaults, so
    #: a baseline keyed by it sees a changed default as a change of metrics, not a missing run.
    written: dict[str, str] = field(default_factory=dict)
    #: The ``[[tuned]]`` tables: configurations run at their per-scene optimum beside their defaults.
    tuned: list[TunedEntry] = field(default_factory=list)

    def config_name(self, spec: str) -> str:
        """The configuration ``spec`` as written in the suite (the truth: its technique name)."""
        return self.written.get(spec, spec.split(":")[0] if spec == self.truth else spec)

    def runs(self) -> int:
        """Number of (scene, configuration) runs, the ground truths not counted."""
        return sum(len(c) for c in self.configurations.values())

    @property
    def notes(self) -> list[str]:
        """Warnings about the suite's scenes (e.g. a family guessed from a scene's name), which
        the study logs before it runs: nothing is refused, but the reader should know."""
        return [e.note for e in self.scenes if e.note]


def builtin_suite_dir() -> Path:
    """The folder of the shipped suites (package data)."""
    return Path(str(resources.files("shadowlab.suites")))


def builtin_suites() -> dict[str, Path]:
    """Shipped suites: name (file stem) → path."""
    return {p.stem: p for p in sorted(builtin_suite_dir().glob("*.toml"))}


def resolve_suite_path(ref: str | Path) -> Path:
    """A shipped suite's name or a path to a suite file → its path (SuiteError if neither)."""
    shipped = builtin_suites()
    if str(ref) in shipped:
        return shipped[str(ref)]
    path = Path(ref)
    if path.is_file():
        return path
    raise SuiteError(f"{ref}: no such suite file, and not a shipped suite{did_you_mean(ref, shipped)} "
                     f"({', '.join(shipped)})")


def load_suite(ref: str | Path) -> Suite:
    """Load and validate a suite by shipped name or path (SuiteError on any problem)."""
    path = resolve_suite_path(ref)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise SuiteError(f"{path}: not valid TOML: {exc}") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise SuiteError(f"{path}: cannot read: {exc}") from exc
    try:
        return parse_suite(data, str(path), path.parent)
    except SceneError as exc:  # TableReader's errors name file and key already
        raise SuiteError(str(exc)) from exc


def _string_list(rd: TableReader, key: str, default=None) -> list[str]:
    val = rd.raw(key, default)
    if not isinstance(val, list) or not all(isinstance(v, str) for v in val):
        raise rd.error(key, f"must be a list of strings, got {val!r}")
    return val


def _scene(ref: str, where: str, file: str, base: Path) -> SceneEntry:
    """Resolve a scene reference (shipped name, or a path relative to the suite file) and check
    that it is a readable TOML file. Its family is the file's ``family`` key, read as strictly as
    a scene load reads it; a file without one gets the family its name suggests
    (:func:`shadowlab.scene.family_from_name`) and a note that says so. A glTF file (``.gltf``,
    ``.glb``) is resolved the same way and read whole here (its lights' types are its own, its
    family ``general``); its camera is its first: a study that wants another names a TOML scene
    that includes the file with ``[gltf] camera = ...``."""
    from ..scene import GENERAL_FAMILY, builtin_scenes, family_from_name, gltf, scene_family_key

    shipped = builtin_scenes()
    if gltf.split_reference(ref)[1] is not None:
        raise SuiteError(f"{file}: {where}: {ref!r}: a suite cannot choose a glTF file's camera with '#'; name a TOML "
                         f"scene that includes the file ([gltf] file = ..., camera = ...)")
    candidates = [base / ref, Path(ref)]
    if ref in shipped:
        path = shipped[ref]
    elif any(c.is_file() for c in candidates):
        path = next(c for c in candidates if c.is_file())
    else:
        raise SuiteError(f"{file}: {where}: unknown scene {ref!r}{did_you_mean(ref, shipped)} (not a shipped scene "
                         f"— see 'shadowlab scenes' — and no file {candidates[0]})")
    if gltf.is_gltf(path):
        from ..scene import load_scene

        try:
            scene = load_scene(path)
        except SceneError as exc:
            raise SuiteError(f"{exc} (scene {ref!r} of {file}: {where})") from None
        return SceneEntry(scene.name, path.resolve(), GENERAL_FAMILY, tuple(l.type_name for l in scene.lights),
                          None, None)
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, OSError, UnicodeDecodeError) as exc:
        raise SuiteError(f"{file}: {where}: scene file {path} cannot be read as TOML: {exc}") from exc
    name = data.get("name", path.stem) if isinstance(data.get("name", path.stem), str) else path.stem
    lights = data.get("lights", [])
    types = tuple(t.get("type", "?") for t in lights if isinstance(t, dict)) if isinstance(lights, list) else ()
    metric = data.get("metric") if isinstance(data.get("metric"), str) else None
    if metric is not None and metric not in judged_columns():
        hint = did_you_mean(metric, judged_columns()) or f" (one of {', '.join(judged_columns())})"
        raise SuiteError(f"{path}: metric: {metric!r} is not a metric column{hint} (scene {ref!r} of {file}: {where})")
    try:
        family, note = scene_family_key(TableReader(data, "", str(path))), None
    except SceneError as exc:
        raise SuiteError(f"{exc} (scene {ref!r} of {file}: {where})") from None
    if family is None:
        family = family_from_name(name)
        note = (f"warning: {path} declares no family; {family!r} guessed from the name {name!r} "
                f"(add family = \"...\" beside metric: docs/contracts.md#scene-files)")
    return SceneEntry(name, path.resolve(), family, types, metric, note)


def _spec(spec: str, where: str, file: str, written: dict[str, str]) -> str:
    """The canonical spec of ``spec`` (SuiteError naming the entry if it is not a technique);
    records how the suite wrote it in ``written`` (first writing wins)."""
    try:
        canonical = from_spec(spec).spec()
    except TechniqueError as exc:
        raise SuiteError(f"{file}: {where}: {exc}") from None
    written.setdefault(canonical, spec.strip())
    return canonical


def _scene_subset(scenes, where: str, file: str, scene_names: set[str]) -> list[str] | None:
    """A table's optional ``scenes`` list, checked against the suite's scenes (None: all)."""
    if scenes is None:
        return None
    if not isinstance(scenes, list) or not all(isinstance(x, str) for x in scenes):
        raise SuiteError(f"{file}: {where}.scenes: must be a list of scene names")
    unknown = [x for x in scenes if x not in scene_names]
    if unknown:
        raise SuiteError(f"{file}: {where}.scenes: {unknown[0]!r} is not one of the suite's scenes"
                         f"{did_you_mean(unknown[0], sorted(scene_names))}")
    return scenes


def _sweep_specs(table, where: str, file: str, scene_names: set[str],
                 written: dict[str, str]) -> tuple[list[str], list[str] | None]:
    """A ``[[sweeps]]`` table → (canonical specs of its grid, the scenes it is limited to or None)."""
    if not isinstance(table, dict):
        raise SuiteError(f"{file}: {where}: must be a table")
    if "technique" not in table or not isinstance(table["technique"], str):
        raise SuiteError(f"{file}: {where}.technique: required, the name of a technique")
    name = table["technique"]
    scenes = _scene_subset(table.get("scenes"), where, file, scene_names)
    axes = {k: (v if isinstance(v, list) else [v]) for k, v in table.items() if k not in ("technique", "scenes")}
    for key, values in axes.items():
        if not values:
            raise SuiteError(f"{file}: {where}.{key}: empty list")
        if any(isinstance(v, (dict, list)) for v in values):
            raise SuiteError(f"{file}: {where}.{key}: values must be numbers, strings or booleans")
    specs = []
    for combo in itertools.product(*axes.values()):
        params = ",".join(f"{k}={format_value(v)}" for k, v in zip(axes, combo))
        specs.append(_spec(f"{name}:{params}" if params else name, f"{where} ({params})", file, written))
    return specs, scenes


#: The default render budget of a ``[[tuned]]`` table's search route.
TUNED_BUDGET = 12


def _tuned_entry(table, where: str, file: str, scene_names: set[str], written: dict[str, str]) -> TunedEntry:
    """A ``[[tuned]]`` table → :class:`TunedEntry`, checked as ``shadowlab tune`` checks its
    arguments (before anything runs)."""
    from ..tuning.space import TuneError
    from ..tuning.tuner import plan_tune

    rd = TableReader(table, where, file)
    spec = rd.string("technique")
    params = _string_list(rd, "params", [])
    objective = rd.string("objective", default="error_rate")
    budget = rd.number("budget", TUNED_BUDGET, min=1, integer=True)
    scenes = _scene_subset(rd.raw("scenes", None), where, file, scene_names)
    rd.finish()
    canonical = _spec(spec, f"{where}.technique", file, written)
    try:
        plan_tune(canonical, params, objective)
    except (TuneError, TechniqueError) as exc:
        raise SuiteError(f"{file}: {where}: {exc}") from None
    return TunedEntry(canonical, spec.strip(), tuple(params), objective, int(budget),
                      tuple(scenes) if scenes is not None else None)


def _check_lights(scenes: list[SceneEntry], configurations: dict[str, list[str]], written: dict[str, str],
                  file: str) -> None:
    """SuiteError, at plan time, for a configuration planned on a scene with a light its
    technique does not render for (``Technique.LIGHTS``: cascades and LiSPSM need a directional
    light, PCSS an area light); limit such a technique to suitable scenes with a sweep's
    ``scenes`` list."""
    for entry in scenes:
        for spec in configurations[entry.name]:
            cls = from_spec(spec)
            for i, kind in enumerate(entry.light_types):
                if not cls.supports_type(kind):
                    raise SuiteError(f"{file}: {written.get(spec, spec)} does not render for light {i} of scene "
                                     f"{entry.name} ({kind}); it {cls.light_requirement()} (limit it to other "
                                     f"scenes with a [[sweeps]] table's scenes list)")


def parse_suite(data: dict, file: str = "<suite>", base: Path | None = None) -> Suite:
    """Build a :class:`Suite` from a parsed TOML dict (``base``: folder scene paths are relative to)."""
    from ..util.validation import RunError, check_size

    base = base or Path.cwd()
    rd = TableReader(data, "", file)
    name = rd.string("name", default=Path(file).stem)
    description = rd.string("description", default="")
    size = rd.raw("size", list(COMPARE_SIZE))
    if not (isinstance(size, list) and len(size) == 2 and all(isinstance(v, int) and not isinstance(v, bool)
                                                               for v in size)):
        raise rd.error("size", f"must be [width, height] in pixels, got {size!r}")
    try:
        size = check_size(tuple(size))
    except RunError as exc:
        raise rd.error("size", str(exc)) from None
    repeat = rd.number("repeat", 5, min=1, integer=True)
    warmup = rd.number("warmup", 1, min=0, integer=True)
    pass_timing = rd.boolean("pass_timing", False)
    scene_refs = _string_list(rd, "scenes")
    if not scene_refs:
        raise rd.error("scenes", "at least one scene is required")
    scenes: list[SceneEntry] = []
    for i, ref in enumerate(scene_refs):
        entry = _scene(ref, f"scenes[{i}]", file, base)
        if any(s.name == entry.name for s in scenes):
            raise SuiteError(f"{file}: scenes[{i}]: scene {entry.name!r} listed twice")
        scenes.append(entry)
    written: dict[str, str] = {}
    techniques = [_spec(s, f"techniques[{i}]", file, written)
                  for i, s in enumerate(_string_list(rd, "techniques", []))]
    sweeps = [_sweep_specs(t, f"sweeps[{i}]", file, {s.name for s in scenes}, written)
              for i, t in enumerate(rd.table_list("sweeps", []))]
    tuned = [_tuned_entry(t, f"tuned[{i}]", file, {s.name for s in scenes}, written)
             for i, t in enumerate(rd.table_list("tuned", []))]
    names: dict[str, int] = {}
    for i, entry in enumerate(tuned):  # two entries of one name would pool their rows as one configuration
        if entry.name in names:
            raise SuiteError(f"{file}: tuned[{i}]: tunes the same configuration and parameters as "
                             f"tuned[{names[entry.name]}] ({entry.name}); remove one")
        names[entry.name] = i
    rd.finish()
    truth = RayTraced().spec()
    configurations = {}
    for s in scenes:
        specs = list(techniques)
        for sweep_specs, only in sweeps:
            if only is None or s.name in only:
                specs.extend(sweep_specs)
        specs.extend(t.spec for t in tuned if t.applies_to(s.name))  # the defaults, beside the optimum
        configurations[s.name] = [sp for sp in dict.fromkeys(specs) if sp != truth]
    if not any(configurations.values()):
        raise SuiteError(f"{file}: no technique configurations (give techniques or [[sweeps]])")
    _check_lights(scenes, configurations, written, file)
    return Suite(name, description, size, repeat, warmup, pass_timing, scenes, configurations, truth, file, written,
                 tuned)

