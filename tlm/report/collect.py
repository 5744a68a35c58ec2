"""The report's inputs: every tlm output folder it is given, read once.

``tlm report`` accepts any folder a tlm command writes, and a folder of such folders at any
depth (``runs/``, ``nest/deep/run1``, a link to a run kept elsewhere: :func:`~tlm.report.folders.find`;
a folder in it with none, and a link out of it to a folder that is no tlm folder, are named in a note;
:func:`~tlm.report.folders.kind_of` tells the kinds):

=================  ==========================================  ================================
kind               written by                                  recognised by
=================  ==========================================  ================================
run                ``tlm run``                                 ``results.json`` (results/1)
sweep              ``tlm sweep``                               ``sweep.yaml`` and ``points/``
thesis             ``tlm thesis``                              ``thesis_comparison.csv``
error-vs-cost      ``tlm error-vs-cost``                       ``rows.jsonl`` + ``reference.json``
granularity        ``tlm granularity``                         ``granularity.jsonl``
scaling            ``tlm scaling``                             ``eq52.json``
extreme            ``tlm extreme``                             ``extreme.jsonl``
=================  ==========================================  ================================

Every run folder found (a run, a thesis cell ``<scene>/<mode>``, a sweep point) becomes
a :class:`Run`; the study tables are kept as rows. A run's files, and a study's cells (a thesis's, an extreme's
cases), are read where its ``.tlm-written`` lists them, where it has one (:mod:`tlm.report.written`: not kept ones).

A file the sections read is checked here (a study's tables in :mod:`tlm.report.study_tables`) for what they
need of it (its columns or keys, numbers where they compute): a damaged one, empty, cut off (a study's tables are
written whole; only ``sweep.jsonl`` is appended to, its last row perhaps cut off by a killed sweep),
not JSON where it should be, or of another shape, is an :class:`~tlm.errors.InputError`
naming the file. :func:`read` leaves out what such a file belongs to (a run, a thesis cell,
a sweep point, a study, a sweep) and lists it in :attr:`Inputs.damaged` (the page's
warnings, a note on stderr), so that one damaged copy does not stop the report of the rest;
where every tlm output given is damaged, the InputError lists them all and no report is
written. A sweep row "ok" whose point's ``results.json`` is gone is read as
``status: missing``; one whose ``results.json`` is damaged, as ``status: damaged``. A point
with two rows (two runs of a sweep killed) is read once (:func:`~tlm.experiments.sweep_rows.one_row_each`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tlm import claims
from tlm.config import MODES
from tlm.errors import InputError, shell_word
from tlm.experiments.sweep_rows import one_row_each
from tlm.report import written
from tlm.report.checks import (  # noqa: F401  (the kinds of value and results.json's keys: importable from here too)
    BOOL,
    COUNT,
    COUNT_OR_NONE,
    ERROR_OPTIONAL,
    FINITE,
    FINITE_OR_NONE,
    IMAGE_OPTIONAL,
    LIST,
    LIST_OR_NONE,
    MAPPING,
    MAPPING_OR_NONE,
    MODE_OR_NONE,
    NUMBER,
    NUMBER_OR_NONE,
    POSITIVE,
    PRESENT,
    RESULTS_KEYS,
    RESULTS_OPTIONAL,
    SCENE_KEYS,
    SCENE_OPTIONAL,
    TEXT,
    TEXTS,
    TIMING_OPTIONAL,
)
from tlm.report.checks import check as _check  # (the file checks by their names here until now)
from tlm.report.checks import counts as _counts  # noqa: F401
from tlm.report.checks import number as _number  # noqa: F401
from tlm.report.checks import read_json as _json
from tlm.report.checks import read_results as _results
from tlm.report.checks import read_yaml as _yaml
from tlm.report.checks import rows_checked as _rows_checked
from tlm.report.checks import short as _short
from tlm.report.folders import find, kind_of, real_path
from tlm.report.names import name_scenes, path_labels, same_file, scene_label, value_text
from tlm.report.once import Reads
from tlm.report.study_tables import study_table, thesis_rows, thesis_summary


@dataclass
class Run:
    """One simulated frame stream: a run folder, a thesis cell or a sweep point."""

    path: Path
    label: str  # short and unique in the report, e.g. "cornell/pmap" or "scaling_ring #3"
    kind: str  # "run", "thesis" or "sweep-point"
    results: dict  # results.json
    config: dict  # config.resolved.yaml
    factors: dict[str, Any] = field(default_factory=dict)  # a sweep point's factor values
    named: str = ""  # the scene's name in the report where :func:`read` set it (see :attr:`scene_label`)
    # a sweep point's --set overrides: its sweep's (sweep.yaml ``overrides``; its results.json has none); None for
    # another run, whose own results.json lists them (:attr:`overrides`)
    sweep_overrides: list[str] | None = None
    listing: Any = field(default=None, init=False, repr=False, compare=False)  # (its .tlm-written: written.names_of)

    @property
    def overrides(self) -> list[str]:
        """The ``--set K=V`` overrides the run was made with: its results.json's ``overrides``, a sweep
        point's its sweep's ([] where none)."""
        return self.sweep_overrides if self.sweep_overrides is not None else overrides_of(self.results)

    @property
    def scene(self) -> str:
        """The scene's ``name`` in its file: two files may share it (the built-in ``room`` and
        ``thesis/room`` are both named ``room``); the report names scenes by :attr:`scene_label`."""
        return str(self.results["scene"]["name"])

    @property
    def scene_label(self) -> str:
        """The scene as the report names it, one name for one scene file (:func:`scene_label`):
        a built-in scene by its name under ``scenes/`` (``thesis/room``, ``room``), another by
        the path its config gave."""
        if self.named:
            return self.named
        scene = self.results.get("scene") or {}
        return scene_label(self.config.get("scene"), scene.get("source"), scene.get("name"))

    @property
    def factors_text(self) -> str:
        """A sweep point's factor values, ``bsp.levels = 7, cache.pairs = 2`` ("" for another run), as
        their YAML writes them (``bsp.levels = null (floor(ln n))``, :func:`~tlm.report.names.value_text`);
        a scene factor by the scene's name in the report."""
        return ", ".join(f"{k} = {self.scene_label if k == 'scene' else value_text(k, v)}"
                         for k, v in self.factors.items())

    @property
    def title(self) -> str:
        """The run's label, and a sweep point's factor values: the point a figure shows."""
        return f"{self.label} ({self.factors_text})" if self.factors else self.label

    @property
    def mode(self) -> str:
        return str(self.results.get("mode") or self.config.get("mode"))

    @property
    def trace(self) -> Path | None:
        return self.wrote("trace.json")

    @property
    def images(self) -> Path | None:
        return self.wrote("images", folder=True)

    @property
    def radiance(self) -> Path | None:
        return self.wrote("radiance", folder=True)

    def wrote(self, rel: str, folder: bool = False) -> Path | None:
        """``path / rel`` where the run wrote it (its ``.tlm-written`` lists it), else None: :func:`written.wrote`,
        the report's one test of a run's files (one a rerun kept from an earlier output is not the run's)."""
        return written.wrote(self, rel, folder)


@dataclass
class Sweep:
    path: Path
    spec: dict  # sweep.yaml
    rows: list[dict]  # sweep.jsonl: the rows of the points sweep.yaml lists
    runs: list[Run]  # its finished points, in point order
    # how the report names it: its folder's name, or where two sweeps of the report share that name, the
    # shortest tail of its path that tells it from the other (``a/sw``, ``b/sw``; :func:`read` sets it)
    label: str = ""
    # (:meth:`run_of`'s lookup: the runs' list it was made of, and its runs by their folder's name)
    _by_name: tuple = field(default=((None, 0), {}), init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.label = self.label or self.path.name

    def run_of(self, row: Any) -> Run | None:
        """The finished point of the sweep's row ``row`` (sweep.jsonl's): the :class:`Run` of its folder
        ``points/<hash>`` (its ``config``, ``results``, ``path``), found by the row's ``hash``; None for a row
        whose point the report did not read (not ok, its folder gone or damaged: its row says ``missing`` or
        ``damaged``), a row of another sweep, one without a hash. Looked up in a map made once per sweep (and
        again where :attr:`runs` is another list or changed length)."""
        (made, n), by_name = self._by_name
        if made is not self.runs or n != len(self.runs):
            by_name = {r.path.name: r for r in self.runs}
            self._by_name = ((self.runs, len(self.runs)), by_name)
        h = row.get("hash") if isinstance(row, dict) else None
        return None if h is None else by_name.get(str(h))  # (no hash: no point, not a folder named "None")

    @property
    def overrides(self) -> list[str]:
        """The ``--set K=V`` overrides the sweep ran with (sweep.yaml ``overrides``), [] where none."""
        return overrides_of(self.spec)

    @property
    def planned(self) -> int:
        """The points sweep.yaml lists (the rows, for a sweep.yaml that lists none)."""
        return len(self.spec.get("points") or []) or len(self.rows)

    @property
    def unfinished(self) -> str:
        """"" for a sweep with a row for every point; else what the report says of the
        points without one (an interrupted sweep, or one still running)."""
        missing = self.planned - len(self.rows)
        return (f"; {missing} of its {self.planned} points not run yet (the sweep was interrupted or is still "
                f"running: the same 'tlm sweep' command finishes it)") if missing > 0 else ""


@dataclass
class Study:
    """A study's result table: ``kind`` is thesis, error-vs-cost, granularity or scaling."""

    kind: str
    path: Path
    rows: list[dict]
    meta: dict = field(default_factory=dict)  # summary / reference / fits

    @property
    def overrides(self) -> list[str]:
        """The ``--set K=V`` overrides the study ran with (its provenance.json's ``overrides``), [] where none."""
        return overrides_of(self.meta.get("provenance"))


def overrides_of(record: Any) -> list[str]:
    """The ``overrides`` a record lists (results.json, sweep.yaml, provenance.json: ``--set``'s
    ``K=V`` texts, in order), [] where it lists none."""
    found = record.get("overrides") if isinstance(record, dict) else None
    return [str(o) for o in found] if isinstance(found, list) else []


def with_set(overrides: list[str]) -> str:
    """``with --set resolution=[32,32], mode=pmap``; "" for none."""
    return f"with --set {', '.join(overrides)}" if overrides else ""


@dataclass
class Inputs:
    dirs: list[Path]
    runs: list[Run] = field(default_factory=list)  # every run, sweep points included
    sweeps: list[Sweep] = field(default_factory=list)
    studies: list[Study] = field(default_factory=list)
    # sweeps read for the scaling section only: the ones a scaling study among the inputs
    # fitted (its idle fractions per PM are drawn; not fitted again, not shown as sweeps)
    scaling_sweeps: list[Sweep] = field(default_factory=list)
    scaling_missing: list[str] = field(default_factory=list)  # sweeps a scaling study recorded, now gone
    # what a section worked out that another quotes, kept so that it is worked out once
    # (the thesis tables' sources: :func:`tlm.report.tables.collect_sources`)
    memo: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    # the files of the inputs that several steps read (a scaling study's sweeps), each read once (:class:`Reads`)
    reads: Reads = field(default_factory=Reads, repr=False, compare=False)
    # what the report says of the folders it was given (:func:`find`): a folder under one with no tlm output in it,
    # a link out of it to a folder that is no tlm folder (not followed), a folder that could not be listed
    notes: list[str] = field(default_factory=list)
    # the damaged files among the inputs, each a line naming the file, its damage, what to do and what the
    # report leaves out for it (:func:`read`); the page lists them with the warnings, stderr as notes
    damaged: list[str] = field(default_factory=list)

    def of_kind(self, kind: str) -> list[Study]:
        return [s for s in self.studies if s.kind == kind]

    def _all_runs(self) -> list[Run]:
        return [*self.runs, *(r for sw in self.scaling_sweeps for r in sw.runs)]

    def unread_cases(self) -> str:
        """What a section that draws runs says of the extreme studies' cases, which are simulated
        but not read as runs (each is a run folder under ``cases/``: ``tlm report`` of that folder
        draws them); "" where the inputs have no extreme case."""
        studies = [(st, len(st.rows)) for st in self.of_kind("extreme") if st.rows]
        if not studies:
            return ""
        n = sum(k for _, k in studies)
        return (f"the {n} case{'s' * (n != 1)} of the extreme stud{'ies' if len(studies) > 1 else 'y'} "
                f"({', '.join(str(st.path) for st, _ in studies)}) were simulated, but this report reads only "
                "their expected and measured behaviour (§8): each case is a run folder under cases/, which "
                f"tlm report {shell_word(str(studies[0][0].path / 'cases'))} draws")

    def scene_of_file(self, source: Any, name: Any = None) -> str:
        """The report's name (:func:`scene_label`) of the scene file ``source``: that of the runs
        that loaded it, else one made from its path (``name``: the scene's name in its file)."""
        if source:
            for r in self._all_runs():
                if same_file((r.results.get("scene") or {}).get("source")) == same_file(source):
                    return r.scene_label
        return scene_label(None, source, name)

    def study_scene(self, study: Study, scene: Any) -> str:
        """A study table's scene (a thesis study's rows name it as its folder, ``ring-2``; another's by
        the name in its file, or eq. 5.2's label) as the report names it: by the scene file of the
        study's cells (:meth:`study_cells`), or of its fits."""
        scene = str(scene)
        if study.kind == "thesis":
            for r in self.study_cells(study, scene):
                return r.scene_label
        if study.kind == "scaling":
            for f in study.meta.get("fits") or []:
                if str(f.get("scene")) == scene and f.get("scene_file"):
                    return self.scene_of_file(f["scene_file"], scene)
        return scene

    def study_cells(self, study: Study, scene: Any = None) -> list[Run]:
        """A thesis study's cells (its run folders ``DIR/<scene>/<mode>``); with ``scene``, those of
        the scene its rows name so: by their folder, as every tlm has named it after the rows, not
        by the name in the scene file, which two scenes of a study may share (the built-in ``ring``,
        ``DIR/ring-2``, beside ``thesis/ring``, ``DIR/ring``; a user's file whose scene is named
        ``ring``). Where no folder is so named, a cell in a folder no row names, by that name."""
        root = study.path.resolve()
        cells = [r for r in self.runs if r.kind == "thesis" and r.path.resolve().parent.parent == root]
        if scene is None:
            return cells
        scene = str(scene)
        found = [r for r in cells if r.path.parent.name == scene]
        if found:
            return found
        named = {str(row.get("scene")) for row in study.rows}
        return [r for r in cells if r.path.parent.name not in named and r.scene == scene]

    def shared_names(self) -> list[tuple[str, list[str]]]:
        """The scenes' names in their files that two or more scenes of the inputs share, each
        with the report's names of those scenes: ``[("room", ["room", "thesis/room"])]``."""
        names: dict[str, set[str]] = {}
        for r in self._all_runs():
            names.setdefault(r.scene, set()).add(r.scene_label)
        return [(n, sorted(labels)) for n, labels in sorted(names.items()) if len(labels) > 1]


# the key a sweep.jsonl row may have that the report reads (the kinds of value, the check of a record's keys and a
# run's results.json: tlm/report/checks.py; a study's tables: tlm/report/study_tables.py)
SWEEP_ROW_OPTIONAL = {"point": (lambda v: isinstance(v, int) and not isinstance(v, bool), "a point number")}


def _run(folder: Path, label: str, kind: str) -> Run:
    results = _results(folder / "results.json")
    cfg_path = folder / "config.resolved.yaml"
    config = (_yaml(cfg_path) if cfg_path.is_file() else {}) or {}
    if not isinstance(config, dict):
        raise InputError(f"is {type(config).__name__} {_short(config)}, not a tlm config", source=str(cfg_path))
    if results.get("mode") is None and config.get("mode") is not None and config["mode"] not in MODES:
        raise InputError(f"is {_short(config['mode'])}, not {MODE_OR_NONE[1]}", source=str(cfg_path), key="mode")
    return Run(folder, label, kind, results, config)



def read(dirs: list[Path], skip: Path | None = None, reads: Reads | None = None) -> Inputs:
    """Read every folder of ``dirs`` or, for a folder that no tlm command wrote, each tlm folder
    under it at any depth (:func:`find`); ``skip``: the report's own folder, not read; ``reads``: the
    report's reads so far (:class:`~tlm.report.once.Reads`; None: a new one), kept as ``inputs.reads``."""
    inputs = Inputs([Path(d) for d in dirs])
    if reads is not None:
        inputs.reads = reads
    folders: list[tuple[Path, str]] = []
    seen: set[str] = set()  # (a folder reached from two of ``dirs`` is read once)
    for d in inputs.dirs:
        if not d.is_dir():
            raise InputError("is not a folder", source=str(d))
        k = kind_of(d)
        said: list[str] = []
        named: list[int] = []  # (how many folders each line of ``said`` names: a line of "and 12 more ...", 12)
        found = [(d, k)] if k is not None else written.own_runs(find(d, skip, said, named), said, named)
        if not found:  # (and what the search passed over: a link not followed, a folder it could not list)
            # (one line: three folders and how many more *folders*, not lines, never "and 1 more" (listing's rule,
            # whose ", " does not fit: "; " between, as a line has commas; and a line may name many folders))
            shown = said if len(said) <= 4 else [*said[:3], f"and {sum(named[3:])} more passed over"]
            raise InputError("holds no tlm output (a run, sweep, thesis, error-vs-cost, granularity, scaling or "
                             "extreme folder) at any depth" + "".join(f"; {n}" for n in shown), source=str(d))
        inputs.notes.extend(said)
        for f, kind in found:
            if real_path(f) not in seen:
                seen.add(real_path(f))
                folders.append((f, kind))
    run_names = dict(zip([f for f, k in folders if k == "run"],
                         path_labels([f for f, k in folders if k == "run"]), strict=True))
    labels: set[str] = set()

    def unique(label: str) -> str:
        out, i = label, 2
        while out in labels:
            out, i = f"{label} ({i})", i + 1
        labels.add(out)
        return out

    labelled: list[tuple[Run, Any]] = []  # each run and how its label reads, given its scene's name

    damaged: list[str] = []  # (each damaged folder's error, with what to do)
    for folder, kind in folders:
        try:
            _folder(inputs, folder, kind, run_names.get(folder, ""), labelled)
        except InputError as e:  # (nothing of the folder was kept: said, and the rest is reported)
            damaged.append(_damage_line(e, AGAIN.get(kind)))
            inputs.damaged.append(f"{damaged[-1]}: {LEFT_OUT[kind].format(folder=folder)}")
    if damaged and not (inputs.runs or inputs.sweeps or inputs.studies):  # (nothing left to report)
        raise InputError(damaged[0] if len(damaged) == 1 else f"every tlm output given is damaged ({len(damaged)} "
                         "folders), so no report is written: " + "; ".join(damaged))
    for sw, label in zip(inputs.sweeps, path_labels([sw.path for sw in inputs.sweeps]), strict=True):
        sw.label = label  # (before the labels of its points, which name it)
    name_scenes(inputs.runs)
    for run, label in labelled:
        run.label = unique(label(run))
    return inputs


# what the report leaves out for a damaged file of a folder of each kind, and what to do about it
LEFT_OUT = {"run": "the run {folder} is left out of this report",
            "thesis": "the thesis study {folder} (its tables and its cells) is left out of this report",
            "sweep": "the sweep {folder} is left out of this report",
            "scaling": "the scaling study {folder} is left out of this report",
            "granularity": "the granularity study {folder} is left out of this report",
            "extreme": "the extreme cases {folder} are left out of this report",
            "error-vs-cost": "the error-vs-cost study {folder} is left out of this report",
            "cell": "its thesis cell {folder} is left out of this report (the thesis tables still show it)",
            "point": "its sweep point {folder} is left out of this report (the sweep's table says 'damaged')"}
AGAIN = {"run": "run it again", "cell": "run the study again", "point": "run the sweep again (tlm sweep with "
         "its sweep file and --out)", "sweep": "run the sweep again"}


def _damage_line(e: InputError, again: str | None) -> str:
    """What the report says of a damaged file: its error, and what to do where it does not say."""
    text = str(e)
    return text if "again" in text else f"{text}; copy it again or {again or 'run the study again'}"


def _folder(inputs: Inputs, folder: Path, kind: str, run_name: str, labelled: list[tuple[Run, Any]]) -> None:
    """Read the tlm ``folder`` of ``kind`` into ``inputs`` (its runs labelled in ``labelled``), or
    nothing of it: an :class:`InputError` naming its damaged file. A damaged thesis cell or sweep point
    leaves out that cell or point alone (in :attr:`Inputs.damaged`)."""
    if kind == "run":
        # (the claim a run killed while it wrote its report left beside its folder, its holder gone: removed,
        # as the next run into the folder would; one held or not provably stale is left)
        claims.drop_stale(folder)
        run = _run(folder, "", "run")
        labelled.append((run, lambda r, name=run_name: f"{name}: {r.scene_label}/{r.mode}"))
        inputs.runs.append(run)
    elif kind == "thesis":
        rows = thesis_rows(folder / "thesis_comparison.csv")
        summary_path = folder / "thesis_summary.json"
        summary = thesis_summary(summary_path) if summary_path.is_file() else {}
        study = Study("thesis", folder, rows, summary)
        _study_records(study, folder)
        cells, damaged = [], []
        found, kept = written.study_cells(folder)  # (a cell the study's listing does not name: not its own)
        for cell in found:
            try:
                cells.append(_run(cell, "", "thesis"))
            except InputError as e:
                damaged.append(f"{_damage_line(e, AGAIN['cell'])}: {LEFT_OUT['cell'].format(folder=cell)}")
        inputs.notes.extend(kept)
        inputs.studies.append(study)
        inputs.damaged.extend(damaged)
        labelled.extend((run, lambda r: f"{r.scene_label}/{r.mode}") for run in cells)
        inputs.runs.extend(cells)
    elif kind == "sweep":
        _sweep(inputs, folder, labelled)
    else:
        _study(inputs, folder, kind)


def _sweep(inputs: Inputs, folder: Path, labelled: list[tuple[Run, Any]]) -> None:
    """The sweep ``folder`` into ``inputs`` (:func:`_folder`)."""
    spec = inputs.reads(folder / "sweep.yaml") or {}  # (read once: a scaling study's checks read it again)
    _check(spec, folder / "sweep.yaml", None, "a tlm sweep's record", {},
           {"points": LIST_OR_NONE, "grid": MAPPING_OR_NONE, "zip": MAPPING_OR_NONE})
    rows = []
    if (folder / "sweep.jsonl").is_file():  # (appended point by point: a last row cut off is left out)
        rows = _rows_checked(folder / "sweep.jsonl", inputs.reads(folder / "sweep.jsonl"), "a tlm sweep's row",
                             {}, SWEEP_ROW_OPTIONAL)
    planned = {str(p.get("hash")) for p in spec.get("points") or [] if isinstance(p, dict)}
    if planned:  # (rows of an earlier sweep into the folder, left by a rerun cut short: not this one's)
        rows = [r for r in rows if str(r.get("hash")) in planned]
    rows = one_row_each(rows)  # (a point's later row in place of its earlier: two runs of the sweep killed)
    runs, sweep_runs, damaged = [], [], []
    for i, row in enumerate(rows if (folder / "points").is_dir() else []):  # (rows alone: no results)
        point = folder / "points" / str(row.get("hash"))
        if row.get("status") != "ok":
            continue
        if not (point / "results.json").is_file():
            # a point whose results are gone is not ok ('tlm scaling' refuses the sweep): the report says so
            rows[i] = {**row, "status": "missing", "error": f"its results.json is missing "
                       f"({point / 'results.json'}): the same 'tlm sweep' command runs it again"}
            continue
        try:
            run = _run(point, "", "sweep-point")
        except InputError as e:  # (the point is not ok: the table says why, the warnings name the file)
            damaged.append(f"{_damage_line(e, AGAIN['point'])}: {LEFT_OUT['point'].format(folder=point)}")
            rows[i] = {**row, "status": "damaged", "error": f"{e}"}
            continue
        run.factors = dict(run.results.get("factors") or {})
        run.sweep_overrides = overrides_of(spec)
        sweep_runs.append((run, row.get("point"), i))
    sweep_runs.sort(key=lambda t: rows[t[2]].get("point", 0))
    runs = [run for run, _, _ in sweep_runs]
    inputs.sweeps.append(Sweep(folder, spec, rows, runs))
    inputs.damaged.extend(damaged)
    labelled.extend((run, lambda r, sw=inputs.sweeps[-1], point=point: f"{sw.label} #{point}")
                    for run, point, _ in sweep_runs)
    inputs.runs.extend(runs)


def _study(inputs: Inputs, folder: Path, kind: str) -> None:
    table = study_table(folder, kind)
    if table is None:
        return
    study = Study(kind, folder, *table)
    _study_records(study, folder)  # (a damaged record: nothing of the study kept)
    inputs.studies.append(study)



def _study_records(study: Study, folder: Path) -> None:
    """A study folder's resolved config and ``provenance.json``, where it has them, into ``study.meta``."""
    for name, key, load in (("config.resolved.yaml", "config", _yaml), ("provenance.json", "provenance", _json)):
        if (folder / name).is_file():
            study.meta[key] = load(folder / name)
    if not isinstance(study.meta.get("provenance", {}), dict):
        raise InputError(f"is {_short(study.meta['provenance'])}, not a tlm provenance record",
                         source=str(folder / "provenance.json"))
