"""Experiments that are suites (``experiments/sm_*.py``): one command line, one study run, one
provenance record, so that each script keeps only its own table or figure.

The study goes to ``<folder of --out>/study-<suite>`` — where ``shadowlab study SUITE`` puts it
when run from the same folder — so the script and the CLI share one cache and whichever runs
second only reads it.
"""
from __future__ import annotations

import argparse
import json
from dataclasses import dataclass
from pathlib import Path

from ..output import provenance
from .runner import StudyOutcome, run_study


@dataclass
class ExperimentRun:
    """A suite run for an experiment: the study's outcome, the output stem (``--out``: the
    script writes ``stem.csv``, ``stem.png``, ...) and the study's record (``renderer``, ``gl``,
    ``timing_method``, ...: the device the workers used, not this process's)."""

    outcome: StudyOutcome
    out: Path
    record: dict

    @property
    def renderer(self) -> str:
        """GL_RENDERER of the workers' device."""
        return self.record["renderer"]

    def write_record(self, **extra) -> Path:
        """The provenance JSON beside ``out`` (``stem.json``): code revision, packages, CPU and
        command line, the workers' GL device, the suite, the study directory, the timing method,
        and ``extra``."""
        self.out.parent.mkdir(parents=True, exist_ok=True)
        return provenance.write_record(self.out, {"gl": self.record["gl"], "suite": self.record.get("study"),
                                                  "study": str(self.outcome.out),
                                                  "timing": self.record.get("timing_method"), **extra},
                                       gl_info=False)

    def save_table(self, df, columns=None) -> tuple[int, int]:
        """Write the experiment's rows ``df`` to ``stem.csv`` (only ``columns`` that it has, in
        that order; all when None) and the provenance record (:meth:`write_record`) with the
        image size, read from the rows' ``width`` / ``height``; return that size."""
        size = (int(df["width"].iloc[0]), int(df["height"].iloc[0]))
        self.write_record(size=list(size))
        table = df if columns is None else df[[c for c in columns if c in df.columns]]
        table.to_csv(self.out.with_suffix(".csv"), index=False)
        return size

    def summary_line(self, *written: Path) -> str:
        """One closing line: renderer, the study directory, tasks run and cached, files written."""
        return (f"renderer: {self.renderer}; study {self.outcome.out} ({self.outcome.ran} tasks run, "
                f"{self.outcome.cached} cached); wrote {' and '.join(str(p) for p in written)}")


def run_experiment_suite(suite: str, description: str, default_out: str, argv=None) -> ExperimentRun:
    """Parse the experiment's command line (``--out STEM``, ``--workers N``, ``--force``), run
    the shipped ``suite`` as a study beside the stem, and return what the script needs. Failed
    runs stop the script (SystemExit naming them): a table with holes is not a result."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--out", default=default_out, help="output stem (CSV, figure, JSON); the study goes beside it")
    ap.add_argument("--workers", type=int, default=None, help="worker processes (default: every core)")
    ap.add_argument("--force", action="store_true", help="ignore the study's cache")
    args = ap.parse_args(argv)
    out = Path(args.out)
    outcome = run_study(suite, out=out.parent / f"study-{suite}", workers=args.workers, force=args.force)
    if outcome.failed:
        raise SystemExit("failed runs in the study:\n" + "\n".join(f"  {f}" for f in outcome.failed))
    record = json.loads((outcome.out / "study.json").read_text())["record"]
    return ExperimentRun(outcome, out, record)
