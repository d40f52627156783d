"""The attempt record of the real machine: `<run_dir>/attempts.csv`, one row per attempt, and
the paper's results table (Table "results summary") computed from it. ROS-free.

The supervisor writes a row when an attempt ends, and rewrites it when the bucket's mass
arrives (the operator's scale or the load cell). Every write replaces the whole file
atomically (a temporary file in the same folder, fsync, os.replace), so a reader never sees a
half-written file and a process that dies later loses nothing already written. Writers read
the file again before each write (read, change one row, replace), so `lhd attempt mass
--run-dir` and the supervisor do not undo each other's rows.

Success (the paper, experimental settings): an attempt succeeds when the loaded mass is at
least 20 kg and the final pitch phi_shovel^T > phi_thresh^pitch (SL >= 1); "loading attempts
that end with a timeout and meet both success conditions are considered successes"; an
attempt that ends in the restricted zone is a failure, and so is one stopped by the e-stop or
by lost input. So `success` is known at the end for failure / estop / lost_input / aborted
(false), and only once weighed for success / timeout.

The table (`summarize`, `format_table`): per controller x material x slope (the attempt's
slope rounded to the nearest 5 deg, halves up): attempts, success rate, and over the SUCCESSFUL attempts
only (the paper: "computed considering only successful loading attempts") the material
loaded, elapsed time, front and rear drift, mean and standard deviation; then the row x-bar
of each metric: the mean across the slopes of the per-slope means, with the standard
deviation of those means (the paper's footnote a; its RLC homogeneous "material loaded"
column 22.40, 24.18, 26.08, 27.24 -> 24.98 +- 1.84 is the population standard deviation,
ddof = 0, which is used throughout). Aborted attempts (the operator, or the supervisor not
starting an attempt whose set-up changed while armed) are not counted, nor are attempts that ended
while armed whatever their outcome (an e-stop, a lost input: they never ran, `never_ran`; counted as
failures until 2026-11-29);
attempts whose success still waits for the weighed mass are listed apart, not counted.
"""
from __future__ import annotations

import csv
import io
import math
import os
import shutil
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

from lhd_loading_ros.task.metrics import success_level

CSV_NAME = "attempts.csv"
COLUMNS = ("attempt", "started_utc", "controller", "slope_deg", "material", "outcome", "reason", "mass_kg",
           "elapsed_s", "front_drift_pct", "rear_drift_pct", "phi_final_deg", "success_level", "success", "bag",
           "config_hash", "phi_thresh_deg")
# the last columns came on 2026-11-29 / 2026-11-30: a record written before has none, and its rows read with them
# empty. phi_thresh_deg is the success test's pitch threshold the supervisor judged the attempt with, so a row is
# weighed offline (`lhd attempt mass --run-dir`) on its own threshold, not on whatever parameter file is at hand
OPTIONAL_COLUMNS = ("config_hash", "phi_thresh_deg")
OUTCOMES = ("success", "failure", "timeout", "estop", "lost_input", "aborted")
NEEDS_MASS = ("success", "timeout")          # success decided by the weighed mass and the final pitch
NOT_COUNTED = ("aborted",)                   # the operator called the attempt off: not in the table
MATERIALS = ("homogeneous", "nonhomogeneous")
# the reason of the row the supervisor writes at arming (task.attempt.Attempt.provisional_row) and
# replaces at the attempt's end: if it stays, the supervisor died first
INTERRUPTED_REASON = ("the supervisor ended during the attempt without recording its end (killed, or the computer "
                      "lost power)")
MAX_MASS_KG = 200.0                          # a bucket rated 30 kg (heaped 37.5): anything above is a typo
SLOPE_BIN_DEG = 5.0
PAPER_ORDER = ("rlc", "rld", "tampier", "teacher", "teleop")
LABELS = {"rlc": "RLC", "rld": "RLD", "tampier": "Tampier", "teacher": "Teacher", "teleop": "Teleop"}


def bag_name(attempt: int) -> str:
    """The attempt's bag folder, relative to the run folder."""
    return f"bags/attempt_{attempt:04d}"


def check_mass(kg) -> float:
    """The weighed mass as a float, or ValueError saying what is wrong and what is expected."""
    try:
        if isinstance(kg, str) and "_" in kg:
            raise ValueError     # Python reads 2_3 as 23: a typo here, not a number
        v = float(kg)
    except (TypeError, ValueError):
        raise ValueError(f"mass {kg!r} is not a number; expected kilograms, e.g. 23.4") from None
    if not math.isfinite(v):
        raise ValueError(f"mass {kg!r} is not a finite number; expected kilograms in [0, {MAX_MASS_KG:g}]")
    if v < 0.0:
        raise ValueError(f"mass {v:g} kg is negative; expected kilograms in [0, {MAX_MASS_KG:g}]")
    if v > MAX_MASS_KG:
        raise ValueError(f"mass {v:g} kg is not a plausible bucket load (the bucket is rated 30 kg); "
                         f"expected kilograms in [0, {MAX_MASS_KG:g}]")
    return v


# The record's resolution: the digits attempts.csv keeps of each number (the scale's 10 g, a hundredth
# of a degree, a millisecond). A row holds its numbers at this resolution (AttemptRow.__post_init__)
# and `judge` decides on them, so the verdict of a live attempt is the one its written row gives again
# when it is read and weighed later (a review: a pitch of 40.004 deg was a success live and, written
# as 40.00, a failure when weighed through the file; 19.996 kg was written 20.00 with success false).
DIGITS = {"slope_deg": 2, "mass_kg": 2, "elapsed_s": 3, "front_drift_pct": 2, "rear_drift_pct": 2,
          "phi_final_deg": 2, "phi_thresh_deg": 3}


def recorded(v: float | None, digits: int) -> float | None:
    """v as attempts.csv writes and reads it back: rounded to `digits` decimals (the same decimal
    rounding as the writer's format); None and non-finite values unchanged."""
    if v is None or not math.isfinite(v):
        return v
    return float(f"{v:.{digits}f}")


def judge(outcome: str, mass_kg: float | None, phi_final_rad: float, phi_thresh_rad: float
          ) -> tuple[int | None, bool | None]:
    """(success level, success) of an attempt: SL from the weighed mass and the final pitch
    (metrics.success_level; a final pitch that was never measured gives SL 0), mass, pitch and
    threshold at the record's resolution (DIGITS), so that the written row judges the same again;
    success as in the module docstring. None where the mass is still needed."""
    if outcome not in OUTCOMES:
        raise ValueError(f"outcome {outcome!r}: expected one of {OUTCOMES}")
    sl = None
    if mass_kg is not None:
        mass_kg = recorded(float(mass_kg), DIGITS["mass_kg"])
        if math.isfinite(phi_final_rad):
            phi_final_rad = math.radians(recorded(math.degrees(phi_final_rad), DIGITS["phi_final_deg"]))
        phi_thresh_rad = math.radians(recorded(math.degrees(phi_thresh_rad), DIGITS["phi_thresh_deg"]))
        sl = success_level(mass_kg, phi_final_rad, phi_thresh_rad) if math.isfinite(phi_final_rad) else 0
    if outcome not in NEEDS_MASS:
        return sl, False
    if sl is None:
        return None, None
    return sl, sl >= 1


@dataclass(frozen=True)
class AttemptRow:
    attempt: int
    started_utc: str
    controller: str
    slope_deg: float
    material: str
    outcome: str
    reason: str
    mass_kg: float | None          # None until weighed
    elapsed_s: float
    front_drift_pct: float
    rear_drift_pct: float
    phi_final_deg: float           # NaN when never measured (written empty)
    success_level: int | None
    success: bool | None
    bag: str
    # the supervisor's parameter file (task.config.config_hash): the zones an attempt was judged on follow
    # from it, so `lhd attempts` says when a folder's attempts come from several; "" where not recorded
    config_hash: str = ""
    # the success test's pitch threshold (deg) of the supervisor's parameter file; NaN where not recorded
    phi_thresh_deg: float = math.nan

    def __post_init__(self):
        # the numbers at the record's resolution: the row in memory is the row in the file
        for name, digits in DIGITS.items():
            object.__setattr__(self, name, recorded(getattr(self, name), digits))

    def weighed(self, mass_kg: float, phi_thresh_rad: float | None = None) -> "AttemptRow":
        """This row with the weighed mass, its SL and success: judged on the row's own pitch
        threshold where it has one, else on `phi_thresh_rad` (ValueError when neither)."""
        m = check_mass(mass_kg)
        if math.isfinite(self.phi_thresh_deg):
            phi_thresh_rad = math.radians(self.phi_thresh_deg)
        elif phi_thresh_rad is None:
            raise ValueError(f"attempt {self.attempt}: the record has no pitch threshold (phi_thresh_deg) and none "
                             "was given")
        sl, ok = judge(self.outcome, m, math.radians(self.phi_final_deg), phi_thresh_rad)
        return replace(self, mass_kg=m, success_level=sl, success=ok)

    @property
    def slope_bin(self) -> float:
        return SLOPE_BIN_DEG * math.floor(self.slope_deg / SLOPE_BIN_DEG + 0.5)     # halves up: 22.5 -> 25

    def to_csv(self) -> dict[str, str]:
        def num(v, digits=2):
            return "" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{digits}f}"

        return {"attempt": str(self.attempt), "started_utc": self.started_utc, "controller": self.controller,
                "slope_deg": num(self.slope_deg, DIGITS["slope_deg"]), "material": self.material,
                "outcome": self.outcome, "reason": self.reason, "mass_kg": num(self.mass_kg, DIGITS["mass_kg"]),
                "elapsed_s": num(self.elapsed_s, DIGITS["elapsed_s"]),
                "front_drift_pct": num(self.front_drift_pct, DIGITS["front_drift_pct"]),
                "rear_drift_pct": num(self.rear_drift_pct, DIGITS["rear_drift_pct"]),
                "phi_final_deg": num(self.phi_final_deg, DIGITS["phi_final_deg"]),
                "success_level": "" if self.success_level is None else str(self.success_level),
                "success": "" if self.success is None else ("true" if self.success else "false"), "bag": self.bag,
                "config_hash": self.config_hash,
                "phi_thresh_deg": num(self.phi_thresh_deg, DIGITS["phi_thresh_deg"])}

    @classmethod
    def from_csv(cls, d: dict, where: str = "") -> "AttemptRow":
        """Parse one CSV row; ValueError naming the row and the column otherwise."""
        at = f"{where}: " if where else ""

        def get(col):
            v = d.get(col)
            if v is None:
                if col in OPTIONAL_COLUMNS:
                    return ""
                raise ValueError(f"{at}column '{col}' missing")
            return v.strip()

        def number(col, optional=False):
            v = get(col)
            if v == "" and optional:
                return None
            try:
                x = float(v)
            except ValueError:
                raise ValueError(f"{at}{col} = {v!r} is not a number") from None
            if not math.isfinite(x):
                raise ValueError(f"{at}{col} = {v!r} is not finite")
            return x

        try:
            attempt = int(get("attempt"))
        except ValueError:
            raise ValueError(f"{at}attempt = {get('attempt')!r} is not an integer") from None
        outcome = get("outcome")
        if outcome not in OUTCOMES:
            raise ValueError(f"{at}outcome = {outcome!r}; expected one of {', '.join(OUTCOMES)}")
        material = get("material")
        if material not in MATERIALS:
            raise ValueError(f"{at}material = {material!r}; expected one of {', '.join(MATERIALS)}")
        sl_raw = get("success_level")
        try:
            sl = None if sl_raw == "" else int(sl_raw)
        except ValueError:
            raise ValueError(f"{at}success_level = {sl_raw!r} is not an integer 0-5") from None
        ok_raw = get("success").lower()
        if ok_raw not in ("", "true", "false"):
            raise ValueError(f"{at}success = {ok_raw!r}; expected true, false or empty")
        phi = number("phi_final_deg", optional=True)
        thresh = number("phi_thresh_deg", optional=True)
        if thresh is not None and not -90.0 <= thresh <= 90.0:
            # the parameter file's own range (task.config: phi_thresh_pitch_deg): what the supervisor writes reads
            raise ValueError(f"{at}phi_thresh_deg = {thresh!r}; expected a pitch threshold in [-90, 90] deg or empty")
        return cls(attempt=attempt, started_utc=get("started_utc"), controller=get("controller"),
                   slope_deg=number("slope_deg"), material=material, outcome=outcome, reason=get("reason"),
                   mass_kg=number("mass_kg", optional=True), elapsed_s=number("elapsed_s"),
                   front_drift_pct=number("front_drift_pct"), rear_drift_pct=number("rear_drift_pct"),
                   phi_final_deg=math.nan if phi is None else phi, success_level=sl,
                   success=None if ok_raw == "" else ok_raw == "true", bag=get("bag"), config_hash=get("config_hash"),
                   phi_thresh_deg=math.nan if thresh is None else thresh)


def csv_path(run_dir) -> Path:
    """attempts.csv of a run folder (a path to the CSV itself is taken as it is)."""
    p = Path(run_dir)
    return p if p.suffix == ".csv" else p / CSV_NAME


def _decimal_comma(names: list[str], fields: list[str], where: str) -> str:
    """'29,90' when joining two neighbouring number fields at a point ('29', '90' -> 29.90) makes the row
    read as an attempt (a spreadsheet's unquoted decimal comma), else ''."""
    for i in range(len(fields) - 1):
        a, b = fields[i].strip(), fields[i + 1].strip()
        if a.lstrip("-").isdigit() and b.isdigit():
            merged = fields[:i] + [f"{a}.{b}"] + fields[i + 2:]
            if len(merged) <= len(names):
                try:
                    AttemptRow.from_csv(dict(zip(names, merged)), where)
                except ValueError:
                    continue
                return f"{a},{b}"
    return ""


def read_rows(path) -> list[AttemptRow]:
    """The rows of an attempts.csv ([] when the file does not exist yet). ValueError, before anything
    is rewritten, for a row that does not read (naming its line and column), a row with more fields than
    the header (a decimal comma from a spreadsheet: 29,90), and an attempt number on two rows. What a
    spreadsheet adds harmlessly is read: a UTF-8 byte-order mark, rows of empty fields."""
    path = Path(path)
    if not path.exists():
        return []
    # utf-8-sig: Excel's UTF-8 starts with a byte-order mark, which read as part of the first column's name
    with open(path, newline="", encoding="utf-8-sig") as f:
        reader = csv.DictReader(f)
        names = reader.fieldnames or []
        missing = [c for c in COLUMNS if c not in names and c not in OPTIONAL_COLUMNS]
        if missing:
            raise ValueError(f"{path}: not an attempts record (columns {', '.join(missing)} missing)")
        rows, lines = [], {}
        for d in reader:
            at = f"{path} line {reader.line_num}"
            extra = d.pop(None, None) or []
            fields = [d[k] for k in names if d[k] is not None] + extra
            if not any(v.strip() for v in fields):
                continue            # a spreadsheet's empty row (only commas, however many)
            if extra:
                guess = _decimal_comma(names, fields, at).replace(",", ".")
                raise ValueError(f"{at} has {len(fields)} fields, expected {len(names)}: a decimal comma? write "
                                 f"{guess or '29.90'} (numbers with a point; text with a comma in double quotes)")
            if any(v is None for k, v in d.items() if k not in OPTIONAL_COLUMNS):   # (those last: may be left out)
                raise ValueError(f"{at} has {len(fields)} fields, expected {len(names)}: a field left out (an empty "
                                 "one is written as nothing between two commas)")
            try:
                row = AttemptRow.from_csv(d, at)
            except ValueError as exc:
                split = _decimal_comma(names, fields, at)
                if split:
                    raise ValueError(f"{at}: {split} reads as two fields (a decimal comma?): write "
                                     f"{split.replace(',', '.')}") from exc
                raise
            if row.attempt in lines:
                raise ValueError(f"{path}: attempt {row.attempt} on lines {lines[row.attempt]} and {reader.line_num}: "
                                 "the record keeps one row per attempt; delete or renumber the wrong one")
            lines[row.attempt] = reader.line_num
            rows.append(row)
        return rows


def write_rows(path, rows: list[AttemptRow]) -> None:
    """Replace `path` atomically with `rows` (sorted by attempt number)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in sorted(rows, key=lambda r: r.attempt):
        w.writerow(r.to_csv())
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        # mkstemp makes it 0600: the record is a lab's shared result, readable as any file the user writes
        # (the mode an open() would give under the process's umask; a review, 2026-11-29)
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)
        with os.fdopen(fd, "w", newline="") as f:
            f.write(buf.getvalue())
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def is_unended(row: AttemptRow) -> bool:
    """The row written at arming, not (yet) replaced by the attempt's end: the attempt is running,
    or its supervisor died during it."""
    return row.outcome == "aborted" and row.reason == INTERRUPTED_REASON


def upsert_row(path, row: AttemptRow) -> None:
    """Write `row` into the record, replacing the row of the same attempt number if present."""
    rows = [r for r in read_rows(path) if r.attempt != row.attempt]
    write_rows(path, rows + [row])


def never_ran_refusal(attempt) -> str:
    """Why a mass for `attempt`, which ended while armed, is refused: one wording for the supervisor,
    `lhd attempt mass` and the launcher's `m KG`."""
    return (f"attempt {attempt} ended before it ran: nothing was loaded. To weigh an earlier attempt: "
            "`lhd attempt mass KG --attempt N`")


def never_ran(row: AttemptRow) -> bool:
    """An attempt that ended while armed (aborted by the operator or by a set-up that changed, the
    e-stop, a silent input): it never ran, so nothing was loaded; the supervisor writes it with an
    elapsed time of 0."""
    return row.elapsed_s == 0.0 and not is_unended(row)


def weigh_row(path, attempt: int | None, mass_kg: float, phi_thresh_rad: float | None = None) -> AttemptRow:
    """Set the mass of attempt `attempt` (None: the latest that ran) in the record; returns the new row.
    Judged on the row's own pitch threshold; `phi_thresh_rad` only for a row recorded without one."""
    rows = read_rows(path)
    if not rows:
        raise ValueError(f"{path}: no attempts recorded")
    live = {r.attempt for r in rows if is_unended(r)}
    idle = {r.attempt for r in rows if never_ran(r)}
    if attempt in idle:
        raise ValueError(f"{path}: attempt {attempt} ended ({[r.outcome for r in rows if r.attempt == attempt][0]}) "
                         "before it ran: nothing was loaded")
    if attempt is None:
        # the latest attempt that ended: the row written at the next one's arming is not it (a
        # review: the mass went to the live attempt's row and was lost when its end replaced it),
        # nor one aborted while armed (a review: the mass of the bucket on the scale went there)
        ended = [r.attempt for r in rows if r.attempt not in live and r.attempt not in idle]
        if not ended:
            raise ValueError(f"{path}: no attempt has ended yet (attempt {max(live)} is running, or its supervisor "
                             "died): weigh the bucket after the attempt ends")
        attempt = max(ended)
    elif attempt in live:
        raise ValueError(f"{path}: attempt {attempt} has no recorded end (it is running, or its supervisor died): "
                         "weigh the bucket after the attempt ends")
    match = [r for r in rows if r.attempt == attempt]
    if not match:
        raise ValueError(f"{path}: no attempt {attempt} (attempts {', '.join(str(r.attempt) for r in rows)})")
    new = match[0].weighed(mass_kg, phi_thresh_rad)
    write_rows(path, [r for r in rows if r.attempt != attempt] + [new])
    return new


# ------------------------------------------------------------------ the paper's table
METRICS = (("mass_kg", "Material loaded [kg]"), ("elapsed_s", "Elapsed time [s]"),
           ("front_drift_pct", "Frontal drift [%]"), ("rear_drift_pct", "Rear drift [%]"))


def _mean_std(xs: list[float]) -> dict:
    if not xs:
        return {"mean": None, "std": None, "n": 0}
    m = sum(xs) / len(xs)
    return {"mean": m, "std": math.sqrt(sum((x - m) ** 2 for x in xs) / len(xs)), "n": len(xs)}


def controller_order(names) -> list[str]:
    names = set(names)
    return [c for c in PAPER_ORDER if c in names] + sorted(names - set(PAPER_ORDER))


def judged_again(row: AttemptRow) -> tuple[int | None, bool | None]:
    """(success level, success) of a row judged again from its own numbers (`judge`), not taken from its
    stored columns, which a hand edit of `mass_kg` leaves stale (a review: 29.90 -> 15.00 kg still counted a
    success). A row with its pitch threshold (phi_thresh_deg) is judged on mass_kg, phi_final_deg and it. A
    row recorded without one (before 2026-11-30) is not judged on some other file's threshold: its stored
    SL says whether the pitch was over its supervisor's threshold (SL >= 1) or, with 20 kg or more, not
    (SL 0), and the mass is judged again; a mass with no stored SL stays unjudged (weigh it again)."""
    if math.isfinite(row.phi_thresh_deg) or row.mass_kg is None:
        return judge(row.outcome, row.mass_kg, math.radians(row.phi_final_deg), math.radians(
            row.phi_thresh_deg if math.isfinite(row.phi_thresh_deg) else 0.0))
    if row.success_level is None:
        return row.success_level, row.success
    # the pitch verdict of the stored SL (SL 0 with under 20 kg says nothing of the pitch: SL 0 either way)
    sl = success_level(row.mass_kg, 1.0, 0.0) if row.success_level >= 1 else 0
    return sl, (sl >= 1) if row.outcome in NEEDS_MASS else False


def summarize(rows: list[AttemptRow]) -> dict:
    """The paper's table as data: `cells` (controller x material x slope), `across_slopes`
    (the x-bar rows), and the attempts left out (aborted; no end recorded; not yet weighed). Each
    counted row is judged again from its numbers (`judged_again`) and counted so; `rejudged` lists
    the rows whose stored success / success_level disagree."""
    left_out = lambda r: r.outcome in NOT_COUNTED or never_ran(r)     # noqa: E731
    rejudged = []
    fixed = []
    for r in rows:
        if not left_out(r):
            sl, ok = judged_again(r)
            if (sl, ok) != (r.success_level, r.success):
                rejudged.append({"attempt": r.attempt, "mass_kg": r.mass_kg,
                                 "stored": {"success_level": r.success_level, "success": r.success},
                                 "judged": {"success_level": sl, "success": ok}})
                r = replace(r, success_level=sl, success=ok)
        fixed.append(r)
    rows = fixed
    aborted = [r.attempt for r in rows if left_out(r) and not is_unended(r)]
    unended = [r.attempt for r in rows if is_unended(r)]
    pending = [r.attempt for r in rows if not left_out(r) and r.success is None]
    counted = [r for r in rows if not left_out(r) and r.success is not None]
    groups: dict[tuple, list[AttemptRow]] = {}
    for r in counted:
        groups.setdefault((r.controller, r.material, r.slope_bin), []).append(r)
    cells = []
    for (ctrl, mat, slope), rs in groups.items():
        ok = [r for r in rs if r.success]
        cell = {"controller": ctrl, "material": mat, "slope_deg": slope, "attempts": len(rs),
                "successes": len(ok), "success_rate": len(ok) / len(rs),
                "attempt_numbers": sorted(r.attempt for r in rs)}
        for key, _ in METRICS:
            cell[key] = _mean_std([getattr(r, key) for r in ok])
        cells.append(cell)
    order = controller_order(c["controller"] for c in cells)
    cells.sort(key=lambda c: (MATERIALS.index(c["material"]), order.index(c["controller"]), c["slope_deg"]))
    across = []
    for mat in MATERIALS:
        for ctrl in order:
            mine = [c for c in cells if c["controller"] == ctrl and c["material"] == mat]
            if not mine:
                continue
            a = {"controller": ctrl, "material": mat, "slopes": [c["slope_deg"] for c in mine]}
            for key, _ in METRICS:
                a[key] = _mean_std([c[key]["mean"] for c in mine if c[key]["mean"] is not None])
            across.append(a)
    # the parameter files the counted attempts were judged with (their zones follow from it): per controller
    files: dict[str, list[str]] = {}
    for r in counted:
        if r.config_hash and r.config_hash not in files.setdefault(r.controller, []):
            files[r.controller].append(r.config_hash)
    return {"rows": len(rows), "counted": len(counted), "aborted": aborted, "unended": unended, "not_weighed": pending,
            "cells": cells, "across_slopes": across, "config_hashes": files, "rejudged": rejudged}


def format_table(summary: dict, title: str = "") -> str:
    """The summary laid out like the paper's table: a block per metric, a line per slope (and
    x-bar), a column per material x controller."""
    cells = summary["cells"]
    lines = [title] if title else []
    def verdict(v):
        ok = {True: "success", False: "no success", None: "waiting for the mass"}[v["success"]]
        return ok + ("" if v["success_level"] is None else f" (SL {v['success_level']})")

    for j in summary.get("rejudged", []):
        mass = "no mass" if j["mass_kg"] is None else f"{j['mass_kg']:.2f} kg"
        lines.append(f"WARNING: attempt {j['attempt']}: the record says {verdict(j['stored'])}, its numbers "
                     f"({mass}) give {verdict(j['judged'])}: counted as {verdict(j['judged'])} (a hand edit? "
                     f"`lhd attempt mass KG --attempt {j['attempt']} --run-dir DIR` rewrites the row)")
    lines.append(f"{summary['rows']} attempt(s) recorded, {summary['counted']} counted")
    if summary["aborted"]:
        lines.append(f"aborted (by the operator, or not started by the supervisor) or ended before they ran, not counted: "
                     f"attempt(s) {', '.join(map(str, summary['aborted']))}")
    if summary.get("unended"):
        lines.append("no end recorded (running now, or its supervisor was killed during it), not counted: attempt(s) "
                     f"{', '.join(map(str, summary['unended']))}")
    if summary["not_weighed"]:
        lines.append(f"not yet weighed, not counted (lhd attempt mass KG --attempt N): attempt(s) "
                     f"{', '.join(map(str, summary['not_weighed']))}")
    hashes = {h for hs in summary.get("config_hashes", {}).values() for h in hs}
    if len(hashes) > 1:
        per = "; ".join(f"{LABELS.get(c, c)} {', '.join(hs)}" for c, hs in summary["config_hashes"].items() if hs)
        lines.append(f"WARNING: the counted attempts were judged with {len(hashes)} parameter files (config hash: {per}): "
                     "their observation and permitted zones may differ; run every session of a comparison with the "
                     "same --config (docs/real_machine.md \"Comparing controllers in one run folder\")")
    if not cells:
        lines.append("no counted attempts yet")
        return "\n".join(lines)
    cols = []       # (material, controller)
    for mat in MATERIALS:
        for ctrl in controller_order(c["controller"] for c in cells if c["material"] == mat):
            cols.append((mat, ctrl))
    slopes = sorted({c["slope_deg"] for c in cells})
    by = {(c["material"], c["controller"], c["slope_deg"]): c for c in cells}
    across = {(a["material"], a["controller"]): a for a in summary["across_slopes"]}
    w0, w1, w = 22, 7, 15

    def fmt_ms(d):
        return "-" if d is None or d["mean"] is None else f"{d['mean']:.2f}±{d['std']:.2f}"

    widths = [w] * len(cols)         # a material's last column widens to fit the material's heading
    head_mat = " " * (w0 + w1)
    for mat in MATERIALS:
        idx = [i for i, (m, _) in enumerate(cols) if m == mat]
        if idx:
            label = mat.capitalize() + " material"
            widths[idx[-1]] += max(0, len(label) + 2 - w * len(idx))
            head_mat += f"{label:<{sum(widths[i] for i in idx)}}"
    rule = "-" * (w0 + w1 + sum(widths))

    def line(name, slope, vals):
        return (f"{name:<{w0}}{slope:<{w1}}" + "".join(f"{v:<{wd}}" for v, wd in zip(vals, widths))).rstrip()

    lines.append(head_mat.rstrip())
    lines.append(line("", "slope", [LABELS.get(c, c) for _, c in cols]))
    lines.append(rule)

    def block(name, value_of, with_mean):
        for i, s in enumerate(slopes):
            vals = ["" if by.get((mat, ctrl, s)) is None else value_of(by[(mat, ctrl, s)]) for mat, ctrl in cols]
            lines.append(line(name if i == 0 else "", f"{s:g}", vals))
        if with_mean:
            vals = [fmt_ms(across[(mat, ctrl)][with_mean]) if (mat, ctrl) in across else "" for mat, ctrl in cols]
            lines.append(line("", "mean", vals))
        lines.append(rule)

    block("Attempts", lambda c: str(c["attempts"]), None)
    block("Success rate", lambda c: f"{c['success_rate']:.2f}", None)
    for key, name in METRICS:
        block(name, lambda c, key=key: fmt_ms(c[key]), key)
    lines.append("metrics over successful attempts only (mean±std); row 'mean': the mean across slopes of the "
                 "per-slope means ± their standard deviation (the paper's x̄)")
    return "\n".join(lines)


def run_dir_problems(run_dir: Path, csv_file: Path, min_free_bytes: float, usage=shutil.disk_usage) -> list[str]:
    """Why the run folder cannot keep an attempt's record and bag now ([] = it can): not a writable folder,
    `attempts.csv` not a writable file, or less than `min_free_bytes` free on its file system (0: not checked).
    The supervisor's preflight (a review, 2026-11-29: on a full disk the attempts ran and nothing was kept)."""
    run_dir, csv_file = Path(run_dir), Path(csv_file)
    if not run_dir.is_dir() or not os.access(run_dir, os.W_OK | os.X_OK):
        return [f"the run folder {run_dir} is not a writable folder: fix it or pick another run_dir"]
    if csv_file.exists() and (not csv_file.is_file() or not os.access(csv_file, os.W_OK)):
        return [f"the record {csv_file} is not a writable file: fix it or pick another run_dir"]
    if min_free_bytes > 0:
        try:
            free = usage(run_dir).free
        except OSError as exc:
            return [f"the run folder {run_dir} cannot be used ({exc})"]
        if free < min_free_bytes:
            return [f"{free / 1e6:.1f} MB free on the run folder's file system ({run_dir}; min_free_mb "
                    f"{min_free_bytes / 1e6:g}): the record and the bag would not be written; free space or pick "
                    "another run_dir"]
    return []
