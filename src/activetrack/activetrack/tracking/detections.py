"""Recorded detections and truth from CSV or JSON files, and back (the formats, columns and
units: docs/track-your-data.md).

A scan is the consecutive rows of one sensor at one epoch (in JSON one entry); a row whose
component cells are all empty is a scan that looked and saw nothing. Every value is checked
before anything is tracked: epochs in non-decreasing order, ``time`` = ``epoch x dt`` (to
:data:`TIME_TOLERANCE`; the scan keeps ``epoch x dt`` exactly, as the simulator computes it),
the sensor one of the configuration's, each component a finite number in its range, the sensors
of one platform at one place per epoch. A bad value is a :class:`DataFileError` naming the
file, the row (the file's line, the header is row 1; in JSON the entry), the column and what is
allowed. The scans of an epoch are kept in the configuration's sensor order (the order the
tracker applies them in), the detections of a scan in file order; each scan's field of view is
its sensor's from where it was (``fov_centre`` for a beam). Floats are written with ``repr``,
so a file written here reads back bit for bit.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from activetrack.data import Scan, TruthSet
from activetrack.limits import MAX_POSITION, MAX_RANGE, MAX_SPEED, MAX_STEPS
from activetrack.models.clutter import ClutteredSensor

__all__ = [
    "DETECTION_COLUMNS",
    "TIME_TOLERANCE",
    "TRUTH_COLUMNS",
    "DataFileError",
    "Detections",
    "SensorTable",
    "component_columns",
    "read_detections",
    "read_truth",
    "truth_set",
    "write_detections",
    "write_truth",
]

# sensor id -> (platform id, the sensor in the scene), in configuration order
SensorTable = Mapping[str, tuple[str, ClutteredSensor]]

DETECTION_COLUMNS = ("epoch", "time", "sensor", "sensor_x", "sensor_y", "sensor_vx", "sensor_vy")
FOV_CENTRE = "fov_centre"
TRUTH_COLUMNS = ("epoch", "target", "x", "y", "vx", "vy")
TIME_TOLERANCE = 1e-6  # s between a file's time and epoch x dt (the graph's stamp tolerance)
POSITION_TOLERANCE = 1e-6  # m between two sensors of one platform at one epoch
MAX_COMPONENT = 1e12  # |value| of a component without a range of its own (a plugin's)
# The range of a component by its name (bearings in [-pi, pi], the simulator's convention).
COMPONENT_RANGES = {
    "bearing": (-math.pi, math.pi),
    "range": (0.0, MAX_RANGE),
    "range_rate": (-MAX_SPEED, MAX_SPEED),
}
_PV_RANGES = ((-MAX_POSITION, MAX_POSITION), (-MAX_SPEED, MAX_SPEED)) * 2  # x, vx, y, vy
_SENSOR_PV = ("sensor_x", "sensor_vx", "sensor_y", "sensor_vy")  # pv order
_TRUTH_PV = ("x", "vx", "y", "vy")
_PV_NAMES = ("x", "xdot", "y", "ydot")

Where = Callable[[str], str]  # column -> "file: row n, column c" (or the JSON entry's path)


class DataFileError(ValueError):
    """A detections, truth or tracks file that cannot be used; the message is one line naming
    the file, the row (or JSON entry) and the column, and what is allowed."""


@dataclass(frozen=True)
class Detections:
    """The scans of a file by epoch (``scans[k]``: epoch k's, in the configuration's sensor
    order; an epoch without scans is absent) and where each scan starts in the file
    (``rows[(k, sensor id)]``, for messages)."""

    source: str
    scans: dict[int, tuple[Scan, ...]]
    rows: dict[tuple[int, str], str] = field(default_factory=dict)

    @property
    def last_epoch(self) -> int:
        return max(self.scans, default=0)

    def at(self, epoch: int) -> tuple[Scan, ...]:
        return self.scans.get(epoch, ())

    @property
    def count(self) -> int:
        """The scans."""
        return sum(len(s) for s in self.scans.values())

    @property
    def detection_count(self) -> int:
        return sum(len(scan.Z) for scans in self.scans.values() for scan in scans)


def component_columns(sensors: SensorTable) -> tuple[str, ...]:
    """The measurement components of the sensors, each once, in sensor order."""
    out: list[str] = []
    for _, sensor in sensors.values():
        out += [c for c in sensor.components if c not in out]
    return tuple(out)


# --- values ------------------------------------------------------------------------------------


def _number(where: Where, column: str, raw: Any, lo: float, hi: float) -> float:
    """A finite number in [lo, hi] from a CSV cell (text) or a JSON value."""
    value: float | None = None
    if isinstance(raw, str):
        with suppress(ValueError):
            value = float(raw.strip())
    elif isinstance(raw, int | float) and not isinstance(raw, bool):
        value = float(raw)
    if value is None or not (math.isfinite(value) and lo <= value <= hi):
        raise DataFileError(
            f"{where(column)}: must be a finite number in [{lo:g}, {hi:g}], got {_shown(raw)}"
        )
    return value


def _integer(where: Where, column: str, raw: Any, lo: int) -> int:
    """An integer in [lo, MAX_STEPS] (no fraction, no bool)."""
    value: int | None = None
    if isinstance(raw, str):
        text = raw.strip()
        value = int(text) if text.lstrip("+-").isdigit() else None
    elif isinstance(raw, int) and not isinstance(raw, bool):
        value = raw
    if value is None or not lo <= value <= MAX_STEPS:
        raise DataFileError(
            f"{where(column)}: must be an integer in [{lo}, {MAX_STEPS}], got {_shown(raw)}"
        )
    return value


def _text(where: Where, column: str, raw: Any) -> str:
    if not isinstance(raw, str) or not raw.strip():
        raise DataFileError(f"{where(column)}: must be a non-empty name, got {_shown(raw)}")
    return raw.strip()


def _time(where: Where, raw: Any, epoch: int, dt: float) -> float:
    """The scans' time: ``epoch x dt`` exactly, the file's checked against it."""
    t = _number(where, "time", raw, -math.inf, math.inf) if _given(raw) else math.nan
    if not abs(t - epoch * dt) <= TIME_TOLERANCE:
        raise DataFileError(
            f"{where('time')}: must be epoch x dt = {epoch} x {dt:g} = {epoch * dt:.9g} s (to "
            f"{TIME_TOLERANCE:g} s), got {_shown(raw)}"
        )
    return epoch * dt


def _pv(where: Where, cells: Mapping[str, Any], columns: Sequence[str]) -> tuple[float, ...]:
    """The pv cells ``columns`` (x, vx, y, vy order), each a finite number in its range."""
    ranges = zip(columns, _PV_RANGES, strict=True)
    return tuple(_number(where, c, cells.get(c), lo, hi) for c, (lo, hi) in ranges)


def _given(raw: Any) -> bool:
    return raw is not None and not (isinstance(raw, str) and not raw.strip())


def _shown(raw: Any) -> str:
    text = repr(raw)
    return text if len(text) <= 40 else text[:40] + "..."


# --- scans -------------------------------------------------------------------------------------


@dataclass
class _Scan:
    """A scan being read: where it starts, its sensor, pv, beam pointing and detections."""

    where: Where
    start: str  # "row n" or "scans[i]"
    epoch: int
    time: float
    sensor_id: str
    pv: tuple[float, ...]
    fov_centre: float | None
    Z: list[list[float]] = field(default_factory=list)
    looked_only: bool = False  # an empty row: the scan saw nothing


class _ScanReader:
    """Checks the fields of each scan of a file (CSV rows or JSON entries) and collects them."""

    def __init__(self, source: str, sensors: SensorTable, dt: float, steps: int | None):
        self.source = source
        self.sensors = sensors
        self.dt = float(dt)
        self.steps = steps
        self.order = {sid: i for i, sid in enumerate(sensors)}
        self.scans: list[_Scan] = []
        self.first: dict[tuple[int, str], str] = {}  # (epoch, sensor) -> where it starts

    def head(self, where: Where, start: str, cells: Mapping[str, Any]) -> _Scan:
        """A scan's epoch, time, sensor, pv and beam pointing, checked."""
        epoch = _integer(where, "epoch", cells.get("epoch"), 1)
        if self.steps is not None and epoch > self.steps:
            raise DataFileError(
                f"{where('epoch')}: must be <= steps {self.steps} (the configuration's), "
                f"got {epoch}"
            )
        time = _time(where, cells.get("time"), epoch, self.dt)
        sensor_id = _text(where, "sensor", cells.get("sensor"))
        if sensor_id not in self.sensors:
            raise DataFileError(
                f"{where('sensor')}: unknown sensor {sensor_id!r}: one of {list(self.sensors)} "
                "(the configuration's)"
            )
        pv = _pv(where, cells, _SENSOR_PV)
        sensor = self.sensors[sensor_id][1]
        raw = cells.get(FOV_CENTRE)
        fov_centre = None
        if sensor.steerable:
            if not _given(raw):
                raise DataFileError(
                    f"{where(FOV_CENTRE)}: sensor {sensor_id!r} has a steerable beam: give the "
                    "bearing it pointed at [rad, world frame]"
                )
            fov_centre = _number(where, FOV_CENTRE, raw, -math.pi, math.pi)
        elif _given(raw):
            raise DataFileError(
                f"{where(FOV_CENTRE)}: only for a sensor with a steerable beam (beam_width); "
                f"sensor {sensor_id!r} has none: leave it empty"
            )
        return _Scan(where, start, epoch, time, sensor_id, pv, fov_centre)

    def detection(self, where: Where, scan: _Scan, cells: Mapping[str, Any]) -> list[float] | None:
        """The detection's components (None: all empty, the scan saw nothing); a component
        of another sensor's kind must be empty."""
        sensor = self.sensors[scan.sensor_id][1]
        own = tuple(sensor.components)
        for column, raw in cells.items():
            if column not in own and _given(raw):
                raise DataFileError(
                    f"{where(column)}: sensor {scan.sensor_id!r} ({sensor.kind}) measures "
                    f"{', '.join(own)}, not {column}: leave {column} empty"
                )
        given = [c for c in own if _given(cells.get(c))]
        if not given:
            return None
        if len(given) < len(own):
            missing = next(c for c in own if c not in given)
            raise DataFileError(
                f"{where(missing)}: sensor {scan.sensor_id!r} ({sensor.kind}) measures "
                f"{', '.join(own)}: give every one (or none: the scan saw nothing)"
            )
        return [
            _number(where, c, cells[c], *COMPONENT_RANGES.get(c, (-MAX_COMPONENT, MAX_COMPONENT)))
            for c in own
        ]

    def add(self, scan: _Scan) -> None:
        """A complete scan, in file order: epochs never go back, one scan per sensor and
        epoch, the sensors of a platform at one place."""
        key = (scan.epoch, scan.sensor_id)
        if self.scans and scan.epoch < self.scans[-1].epoch:
            raise DataFileError(
                f"{scan.where('epoch')}: epochs out of order: {scan.epoch} after "
                f"{self.scans[-1].epoch} ({self.scans[-1].start}); the scans go in epoch order"
            )
        if key in self.first:
            raise DataFileError(
                f"{scan.where('sensor')}: a second scan of {scan.sensor_id!r} at epoch "
                f"{scan.epoch} (the first at {self.first[key]}): the rows of a scan are "
                "consecutive"
            )
        platform = self.sensors[scan.sensor_id][0]
        for other in reversed(self.scans):
            if other.epoch != scan.epoch:
                break
            if self.sensors[other.sensor_id][0] == platform and not np.allclose(
                other.pv, scan.pv, rtol=0.0, atol=POSITION_TOLERANCE
            ):
                raise DataFileError(
                    f"{scan.where('sensor_x')}: sensor {scan.sensor_id!r} is on platform "
                    f"{platform!r} with {other.sensor_id!r}, which was at {list(other.pv)} at "
                    f"epoch {scan.epoch} ({other.start}): a platform is at one place per epoch"
                )
        self.first[key] = scan.start
        self.scans.append(scan)

    def detections(self) -> Detections:
        """The scans by epoch, each epoch's in sensor order."""
        by_epoch: dict[int, list[Scan]] = {}
        for s in self.scans:
            sensor = self.sensors[s.sensor_id][1]
            pv = np.array(s.pv, dtype=float)
            Z = np.array(s.Z, dtype=float).reshape(len(s.Z), int(sensor.dim_z))
            fov = sensor.field_of_view(pv, s.fov_centre)
            by_epoch.setdefault(s.epoch, []).append(Scan(s.sensor_id, s.epoch, s.time, pv, Z, fov))
        scans = {
            k: tuple(sorted(v, key=lambda scan: self.order[scan.sensor_id]))
            for k, v in by_epoch.items()
        }
        rows = {(s.epoch, s.sensor_id): s.start for s in self.scans}
        return Detections(self.source, scans, rows)


def read_detections(
    path: str | Path, sensors: SensorTable, dt: float, steps: int | None = None
) -> Detections:
    """The scans of a CSV or JSON file (module docstring) for these sensors (their ids, kinds'
    components and beams), epochs ``dt`` apart and at most ``steps``; DataFileError (one line)
    for anything else."""
    path = Path(path)
    reader = _ScanReader(str(path), sensors, dt, steps)
    read = {".csv": _read_csv_scans, ".json": _read_json_scans}.get(path.suffix.lower())
    if read is None:
        raise DataFileError(f"{path}: detections must be a .csv or .json file (or a bag)")
    read(path, reader)
    if not reader.scans:
        raise DataFileError(f"{path}: holds no scans")
    return reader.detections()


def _csv_rows(path: Path, required: Sequence[str], optional: Sequence[str]):
    """``(row number, {column: cell})`` of a CSV file whose header has every required column
    and no unknown one."""
    try:
        f = path.open(newline="", encoding="utf-8")
    except OSError as exc:
        raise DataFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    with f:
        rows = csv.reader(f)
        try:
            header = [c.strip() for c in next(rows, [])]
            allowed = (*required, *optional)
            for column in header:
                if column not in allowed or header.count(column) > 1:
                    what = "twice" if column in allowed else f"unknown: one of {list(allowed)}"
                    raise DataFileError(f"{path}: row 1 (the header), column {column!r}: {what}")
            for column in required:
                if column not in header:
                    raise DataFileError(
                        f"{path}: row 1 (the header): missing column {column!r} (the "
                        f"columns: {', '.join(required)}, then {', '.join(optional)})"
                    )
            for cells in rows:
                if not any(c.strip() for c in cells):
                    continue  # a blank line
                if len(cells) != len(header):
                    raise DataFileError(
                        f"{path}: row {rows.line_num}: has {len(cells)} cells, the header "
                        f"{len(header)}"
                    )
                yield rows.line_num, dict(zip(header, cells, strict=True))
        except (csv.Error, UnicodeDecodeError) as exc:
            raise DataFileError(f"{path}: row {rows.line_num}: not CSV text: {exc}") from None


def _read_csv_scans(path: Path, reader: _ScanReader) -> None:
    components = component_columns(reader.sensors)
    steerable = any(s.steerable for _, s in reader.sensors.values())
    optional = (*components, *((FOV_CENTRE,) if steerable else ()))
    scan: _Scan | None = None
    for n, cells in _csv_rows(path, DETECTION_COLUMNS, optional):

        def where(column: str, n: int = n) -> str:
            return f"{path}: row {n}, column {column}"

        head = reader.head(where, f"row {n}", cells)
        sensor = reader.sensors[head.sensor_id][1]
        for c in sensor.components:
            if c not in cells:
                raise DataFileError(
                    f"{where(c)}: sensor {head.sensor_id!r} ({sensor.kind}) measures "
                    f"{', '.join(sensor.components)}: the header has no column {c!r}"
                )
        z = reader.detection(where, head, {c: cells.get(c) for c in components})
        if scan is not None and (scan.epoch, scan.sensor_id) == (head.epoch, head.sensor_id):
            _same_scan(where, scan, head)
            if z is None or scan.looked_only:
                first = scan.start
                raise DataFileError(
                    f"{where(components[0])}: an empty row is a scan without detections; the "
                    f"scan of {head.sensor_id!r} at epoch {head.epoch} ({first}) has both"
                )
            scan.Z.append(z)
            continue
        if scan is not None:
            reader.add(scan)
        scan = head
        scan.looked_only = z is None
        if z is not None:
            scan.Z.append(z)
    if scan is not None:
        reader.add(scan)


def _same_scan(where: Where, scan: _Scan, head: _Scan) -> None:
    """The rows of one scan give the same sensor state and beam pointing."""
    for column, a, b in (
        *zip(_SENSOR_PV, scan.pv, head.pv, strict=True),
        (FOV_CENTRE, scan.fov_centre, head.fov_centre),
    ):
        if a != b:
            raise DataFileError(
                f"{where(column)}: the rows of a scan give the same {column}: "
                f"{a!r} at {scan.start}, {b!r} here"
            )


def _json_document(path: Path, key: str) -> list:
    """The list under ``key`` of a JSON file holding an object."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise DataFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise DataFileError(f"{path}: not JSON: {exc}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get(key), list):
        raise DataFileError(f'{path}: must hold an object {{"{key}": [...]}}')
    unknown = sorted(set(doc) - {key})
    if unknown:
        raise DataFileError(f"{path}: unknown key {unknown[0]!r}: the file holds {key!r}")
    return doc[key]


def _read_json_scans(path: Path, reader: _ScanReader) -> None:
    allowed = {*DETECTION_COLUMNS, FOV_CENTRE, "detections"}
    components = component_columns(reader.sensors)
    for i, entry in enumerate(_json_document(path, "scans")):

        def where(column: str, i: int = i) -> str:
            return f"{path}: scans[{i}].{column}"

        if not isinstance(entry, dict):
            raise DataFileError(f"{path}: scans[{i}]: must be an object (a scan)")
        for key in entry:
            if key not in allowed:
                raise DataFileError(f"{where(key)}: unknown: one of {sorted(allowed)}")
        scan = reader.head(where, f"scans[{i}]", entry)
        found = entry.get("detections")
        if not isinstance(found, list):
            raise DataFileError(
                f"{where('detections')}: must be a list of detections ([] for a scan that "
                "saw nothing)"
            )
        for j, d in enumerate(found):

            def at(column: str, j: int = j, i: int = i) -> str:
                return f"{path}: scans[{i}].detections[{j}].{column}"

            if not isinstance(d, dict) or any(c not in components for c in d):
                raise DataFileError(
                    f"{path}: scans[{i}].detections[{j}]: must be an object of components "
                    f"{list(components)}, got {_shown(d)}"
                )
            z = reader.detection(at, scan, d)
            if z is None:
                raise DataFileError(
                    f"{path}: scans[{i}].detections[{j}]: empty (a scan that saw nothing "
                    "has detections: [])"
                )
            scan.Z.append(z)
        reader.add(scan)


def write_detections(path: str | Path, scans: Iterable[Scan], sensors: SensorTable) -> None:
    """The scans as a CSV or JSON file (module docstring), floats exact."""
    path = Path(path)
    components = component_columns(sensors)
    steerable = any(s.steerable for _, s in sensors.values())
    entries = []
    for scan in scans:
        sensor = sensors[scan.sensor_id][1]
        entry: dict[str, Any] = {
            "epoch": int(scan.epoch),
            "time": float(scan.time),
            "sensor": scan.sensor_id,
            **{c: float(v) for c, v in zip(_SENSOR_PV, scan.sensor_pv, strict=True)},
        }
        if sensor.steerable:
            entry[FOV_CENTRE] = float(scan.fov.centre)
        own = tuple(sensor.components)
        Z = np.asarray(scan.Z, dtype=float).reshape(-1, len(own))
        entry["detections"] = [dict(zip(own, map(float, z), strict=True)) for z in Z]
        entries.append(entry)
    columns = [*DETECTION_COLUMNS, *components, *((FOV_CENTRE,) if steerable else ())]
    rows = ({**e, **z} for e in entries for z in e["detections"] or [{}])  # CSV: per detection
    _write_entries(path, "scans", entries, columns, rows)


def _write_entries(
    path: Path, key: str, entries: list, columns: Sequence[str], rows: Iterable[dict]
) -> None:
    """``{key: entries}`` as JSON, or ``rows`` as CSV ``columns`` (floats exact, None empty)."""
    if path.suffix.lower() == ".json":
        path.write_text(json.dumps({key: entries}, indent=1) + "\n")
        return
    with path.open("w", newline="") as f:
        out = csv.writer(f)
        out.writerow(columns)
        for cells in rows:
            out.writerow([_cell(cells.get(c)) for c in columns])


def _cell(value: Any) -> str:
    if value is None:
        return ""
    return repr(value) if isinstance(value, float) else str(value)


# --- truth -------------------------------------------------------------------------------------


def read_truth(path: str | Path, dt: float) -> dict[int, TruthSet]:
    """The targets alive at each epoch of a truth file (module docstring), epochs ``dt``
    apart; DataFileError (one line) for anything else."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        rows = [
            (lambda c, n=n: f"{path}: row {n}, column {c}", f"row {n}", cells)
            for n, cells in _csv_rows(path, TRUTH_COLUMNS, ("time",))
        ]
    elif suffix == ".json":
        rows = []
        for i, entry in enumerate(_json_document(path, "truth")):
            if not isinstance(entry, dict) or not set(entry) <= {*TRUTH_COLUMNS, "time"}:
                raise DataFileError(
                    f"{path}: truth[{i}]: must be an object of {[*TRUTH_COLUMNS, 'time']}"
                )
            rows.append((lambda c, i=i: f"{path}: truth[{i}].{c}", f"truth[{i}]", entry))
    else:
        raise DataFileError(f"{path}: truth must be a .csv or .json file (or a bag)")
    return _truth_sets(rows, dt, str(path))


def _truth_sets(rows: list, dt: float, source: str) -> dict[int, TruthSet]:
    targets: dict[int, dict[str, np.ndarray]] = {}
    first: dict[tuple[int, str], str] = {}
    last = (0, "")
    for where, start, cells in rows:
        epoch = _integer(where, "epoch", cells.get("epoch"), 0)
        if _given(cells.get("time")):
            _time(where, cells.get("time"), epoch, dt)
        target = _text(where, "target", cells.get("target"))
        if epoch < last[0]:
            raise DataFileError(
                f"{where('epoch')}: epochs out of order: {epoch} after {last[0]} ({last[1]}); "
                "the rows go in epoch order"
            )
        if (epoch, target) in first:
            raise DataFileError(
                f"{where('target')}: target {target!r} at epoch {epoch} twice (first at "
                f"{first[(epoch, target)]})"
            )
        first[(epoch, target)] = start
        last = (epoch, start)
        targets.setdefault(epoch, {})[target] = np.array(_pv(where, cells, _TRUTH_PV))
    if not targets:
        raise DataFileError(f"{source}: holds no truth")
    return {k: truth_set(k, k * dt, by_id) for k, by_id in targets.items()}


def truth_set(epoch: int, time: float, by_id: Mapping[str, np.ndarray]) -> TruthSet:
    """The targets ``{id: pv (4,)}`` alive at an epoch as a TruthSet (their pv states)."""
    ids = tuple(by_id)
    pv = np.array([by_id[i] for i in ids], dtype=float).reshape(-1, 4)
    return TruthSet(
        epoch, time, ids, pv, tuple(row.copy() for row in pv), tuple(_PV_NAMES for _ in ids)
    )


def write_truth(path: str | Path, truth: Iterable[TruthSet]) -> None:
    """Truth sets as a CSV or JSON truth file (floats exact)."""
    path = Path(path)
    entries = [
        {"epoch": int(t.epoch), "time": float(t.time), "target": tid}
        | {c: float(v) for c, v in zip(_TRUTH_PV, pv, strict=True)}
        for t in truth
        for tid, pv in zip(t.ids, np.asarray(t.pv, dtype=float).reshape(-1, 4), strict=True)
    ]
    _write_entries(path, "truth", entries, [*TRUTH_COLUMNS, "time"], entries)
