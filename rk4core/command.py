"""External programs as methods: the file protocol (version 1).

A **command** method is a program in any language that integrates one
problem on a fixed step grid. The harness owns the problem, the truth and
every metric; the program only turns a problem file into a trajectory file.

The command line
----------------
A command is an argv list (no shell). Four placeholders are replaced, in any
argument, by absolute paths:

``{problem}``      the problem file, ``<workdir>/problem.json``
``{trajectory}``   the file the program writes, ``<workdir>/trajectory.csv``
``{workdir}``      the run's private directory (also the program's cwd)
``{thesis_code}``  ``rk4core/thesis_code``: the thesis' Code 01-03 for GNU
                   Octave and their drivers (``run_code01_ode45.m``,
                   ``run_code01_euler.m``, ``run_code02.m``, ``run_code03.m``)

for example ``["octave-cli", "--no-history", "--norc", "--quiet",
"{thesis_code}/run_code03.m", "{problem}", "{trajectory}", "printed"]``.

A run
-----
1. The harness creates a fresh private directory (``tempfile.mkdtemp``,
   mode 0700) and writes ``problem.json`` into it.
2. It runs the program there: no shell, stdin closed (``/dev/null``), stdout
   and stderr captured (the last 4000 characters of each are kept), in a
   session of its own, with a timeout (default :data:`DEFAULT_TIMEOUT`
   s; on expiry the program's whole process group is killed).
3. It reads ``trajectory.csv`` (and ``stats.json`` if present) and checks
   them (below).
4. It removes what is in the directory, then the directory. The directory was
   created empty, private to the user, for this run only, so everything in
   it is the harness' own ``problem.json``, the protocol's outputs, or what
   the program left there during the run: all of it is removed, symbolic
   links as links (their targets are never touched) and subdirectories
   without following links (``shutil.rmtree``'s file-descriptor walk; where
   the platform lacks it, left-over subdirectories are kept and the result
   says so). Nothing outside the directory is removed. If the path no longer
   is that directory (replaced, renamed, a link), nothing is removed and the
   result's message says so. Names the program left besides the protocol's
   files are listed in ``CommandResult.leftovers``. A program must not leave
   processes running after it exits.

``problem.json``
----------------
A JSON object (strict JSON: no NaN or Infinity):

``protocol``          1
``model``             the model's name (``"chain"``, ``"planar4"``, ...)
``params``            the model's parameters (``model.params()``)
``n_dof``             n, the number of generalized coordinates
``coordinates``       their names
``layout``            ``"y = [q_1..q_n, v_1..v_n]"``: the state is the n
                      coordinates, then the n velocities (SI units)
``y0``                the initial state (2n numbers) at ``t0``
``t0``, ``t_end``     the interval (s)
``h``, ``n_steps``    the step (s) and the number of steps:
                      ``t_end = t0 + n_steps h``
``t_eval``            the output times (s), increasing, each on the step grid
                      ``t0 + i h``
``stiffness_matrix``  linear models only (n <= 1000): K (n x n, N/m) so that
``masses``            with M = diag(masses) (kg) the equations are
                      ``q' = v, M v' = -K q``: a program can build y' = A y
                      without the harness' model code
``rhs``               the equations in words

``trajectory.csv``
------------------
A header ``t,y1,...,yN`` (N = 2n), then one row per state, comma-separated
numbers (``%.17g`` round-trips; ``NaN``/``Inf`` are read as such in y, never
in t). Either one row per step (``n_steps + 1`` rows at ``t = t0 + i h``) or
exactly the ``t_eval`` rows, in order. A row's time matches its grid time when
they differ by at most ``1e-9 h`` (plus 4 ulp of the largest |t|, so the
rounding of a long horizon never fails). The harness picks the rows at
``t_eval``; the times it reports are its own ``t_eval``.

``stats.json`` (optional, beside the trajectory): ``{"nfev": <int >= 0>}``,
the program's count of right-hand-side evaluations.

Outcomes
--------
:func:`run_command` never raises for a program's failure; it returns a
:class:`CommandResult` with ``status``:

``"ok"``           the trajectory was read and checked;
``"unavailable"``  the program is not installed (message: ``"octave-cli not
                   found on PATH; install GNU Octave (apt-get install -y
                   octave)"``);
``"failed"``       a non-zero exit (message: the exit status and the last line
                   of stderr), a timeout, or output that breaks the rules
                   above (message: which rule, which line).

A problem that is not a valid protocol-1 problem is the caller's error
(``ValueError``).
"""
from __future__ import annotations

import json
import math
import os
import shutil
import signal
import stat
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["PROTOCOL_VERSION", "THESIS_CODE", "PROBLEM_FILE", "TRAJECTORY_FILE", "STATS_FILE", "LAYOUT",
           "DEFAULT_TIMEOUT", "CommandResult", "run_command", "expand_argv", "read_trajectory",
           "check_problem", "OutputError"]

PROTOCOL_VERSION = 1
#: The thesis' programs for GNU Octave and their drivers.
THESIS_CODE = Path(__file__).resolve().with_name("thesis_code")
PROBLEM_FILE = "problem.json"
TRAJECTORY_FILE = "trajectory.csv"
STATS_FILE = "stats.json"
LAYOUT = "y = [q_1..q_n, v_1..v_n]"
#: Seconds a program may run before it is killed.
DEFAULT_TIMEOUT = 600.0
#: Relative (to h) tolerance on a trajectory row's time.
TIME_RTOL = 1e-9
_TAIL = 4000
_STATS_MAX = 65536
#: How to install a program the harness knows by name.
INSTALL_HINTS = {
    "octave-cli": "install GNU Octave (apt-get install -y octave)",
    "octave": "install GNU Octave (apt-get install -y octave)",
}
#: A line GNU Octave 7 may print on stderr at a normal exit; never "the last
#: stderr line" of a failure.
_NOISE = ("error: ignoring const execution_exception& while preparing to exit",)


class OutputError(ValueError):
    """The program's output breaks the protocol; the message says how."""


@dataclass
class CommandResult:
    """One run of a command.

    Attributes
    ----------
    t : ndarray, shape (m,)
        The problem's ``t_eval`` (s) when ``status == "ok"``, else empty.
    y : ndarray, shape (2n, m)
        The states at ``t`` (empty when not ok).
    nfev : int or None
        ``stats.json``'s count, None without it.
    wall_s : float
        Wall time of the program (s), its start-up included.
    status : {"ok", "failed", "unavailable"}
    message : str
        Empty when ok (or a note on the clean-up); else one line.
    argv : list of str
        The command line as run (placeholders replaced).
    returncode : int or None
    stdout, stderr : str
        The last 4000 characters of each.
    leftovers : tuple of str
        Names the program left in its directory besides the protocol's files
        (all removed).
    """

    t: np.ndarray
    y: np.ndarray
    nfev: int | None
    wall_s: float
    status: str
    message: str
    argv: list = field(default_factory=list)
    returncode: int | None = None
    stdout: str = ""
    stderr: str = ""
    leftovers: tuple = ()

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def expand_argv(argv, *, problem, trajectory, workdir) -> list[str]:
    """``argv`` with ``{problem}``, ``{trajectory}``, ``{workdir}`` and
    ``{thesis_code}`` replaced (plain text replacement; other braces stay)."""
    if isinstance(argv, (str, bytes)) or not argv:
        raise ValueError(f"`argv` must be a non-empty list of strings (no shell), got {argv!r:.80}")
    out = []
    for a in argv:
        if not isinstance(a, str) or not a:
            raise ValueError(f"`argv` must hold non-empty strings, got {a!r:.80}")
        for key, value in (("{problem}", problem), ("{trajectory}", trajectory), ("{workdir}", workdir),
                           ("{thesis_code}", str(THESIS_CODE))):
            a = a.replace(key, str(value))
        out.append(a)
    return out


def check_problem(problem: dict) -> dict:
    """``problem`` if it is a protocol-1 problem (the fields the harness reads
    back); else ``ValueError`` naming the field."""
    if not isinstance(problem, dict):
        raise ValueError(f"`problem` must be a dict, got {type(problem).__name__}")
    if problem.get("protocol") != PROTOCOL_VERSION:
        raise ValueError(f"`problem.protocol` must be {PROTOCOL_VERSION}, got {problem.get('protocol')!r}")
    n = problem.get("n_dof")
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"`problem.n_dof` must be an integer >= 1, got {n!r}")
    if len(problem.get("y0", ())) != 2 * n:
        raise ValueError(f"`problem.y0` must have 2 n_dof = {2 * n} entries")
    ns = problem.get("n_steps")
    if isinstance(ns, bool) or not isinstance(ns, int) or ns < 1:
        raise ValueError(f"`problem.n_steps` must be an integer >= 1, got {ns!r}")
    t0, h = float(problem["t0"]), float(problem["h"])
    if not (math.isfinite(t0) and math.isfinite(h) and h > 0):
        raise ValueError(f"`problem.t0` and `problem.h` must be finite, h > 0, got {t0!r}, {h!r}")
    te = np.asarray(problem.get("t_eval", ()), dtype=float)
    if te.ndim != 1 or te.size < 1 or not np.all(np.isfinite(te)) or np.any(np.diff(te) <= 0):
        raise ValueError("`problem.t_eval` must be a non-empty increasing list of finite times")
    idx = np.rint((te - t0) / h)
    if np.any(idx < 0) or np.any(idx > ns) or np.any(np.abs(te - (t0 + idx * h)) > _time_tol(h, te, t0)):
        raise ValueError("`problem.t_eval` must lie on the step grid t0 + i h, 0 <= i <= n_steps")
    return problem


def _time_tol(h, *times) -> float:
    big = max((float(np.max(np.abs(np.atleast_1d(t)))) for t in times), default=0.0)
    return TIME_RTOL * h + 4.0 * np.spacing(big)


def _program_missing(prog: str) -> str | None:
    """Why ``prog`` cannot be started, or None."""
    hint = INSTALL_HINTS.get(os.path.basename(prog), "install it or give its full path")
    if os.sep in prog or (os.altsep and os.altsep in prog):
        if not os.path.isfile(prog):
            return f"{prog} not found; {hint}"
        if not os.access(prog, os.X_OK):
            return f"{prog} is not executable"
        return None
    if shutil.which(prog) is None:
        return f"{prog} not found on PATH; {hint}"
    return None


def _tail(fh) -> str:
    fh.flush()
    size = fh.seek(0, os.SEEK_END)
    fh.seek(max(0, size - 4 * _TAIL))
    return fh.read().decode("utf-8", "replace")[-_TAIL:]


def _last_line(*texts) -> str:
    for text in texts:
        lines = [ln.strip() for ln in text.splitlines() if ln.strip() and ln.strip() not in _NOISE]
        if lines:
            return lines[-1][:300]
    return "(no output)"


def _read_regular(path: Path, limit: int) -> bytes | None:
    """The bytes of ``path`` if it is a regular file (not a link) of at most
    ``limit`` bytes; None if it does not exist; OutputError otherwise."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        return None
    except OSError as e:
        raise OutputError(f"{path.name} cannot be opened ({e.strerror or e}; a symbolic link is refused)") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise OutputError(f"{path.name} is not a regular file")
        if st.st_size > limit:
            raise OutputError(f"{path.name} has {st.st_size} bytes, more than the {limit} a trajectory of this "
                              f"problem can need")
        with os.fdopen(fd, "rb", closefd=True) as f:
            fd = -1
            return f.read(limit + 1)
    finally:
        if fd >= 0:
            os.close(fd)


def read_trajectory(path, problem: dict) -> tuple[np.ndarray, np.ndarray]:
    """``(t, y)`` at the problem's ``t_eval`` from a trajectory file;
    ``OutputError`` naming the broken rule.

    ``t`` is the problem's ``t_eval``; ``y`` has shape (2n, len(t_eval)).
    """
    path = Path(path)
    n_state = 2 * int(problem["n_dof"])
    t0, h, ns = float(problem["t0"]), float(problem["h"]), int(problem["n_steps"])
    t_eval = np.asarray(problem["t_eval"], dtype=float)
    limit = 64 * (n_state + 1) * (ns + 2) + 2**20
    raw = _read_regular(path, limit)
    if raw is None:
        raise OutputError(f"the program wrote no {path.name}")
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError:
        raise OutputError(f"{path.name} is not ASCII text") from None
    lines = text.replace("\r\n", "\n").split("\n")
    header = [c.strip() for c in lines[0].split(",")]
    want = ["t"] + [f"y{i}" for i in range(1, n_state + 1)]
    if header != want:
        shown = lines[0][:80]
        raise OutputError(f"{path.name}: the header must be 't,y1,...,y{n_state}' ({n_state + 1} columns for "
                          f"n_dof = {n_state // 2}), got {shown!r}")
    body = [(i + 2, ln) for i, ln in enumerate(lines[1:]) if ln.strip()]
    data = np.empty((len(body), n_state + 1))
    for r, (lineno, ln) in enumerate(body):
        cells = ln.split(",")
        if len(cells) != n_state + 1:
            raise OutputError(f"{path.name} line {lineno}: {len(cells)} columns, expected {n_state + 1}")
        try:
            data[r] = [float(c) for c in cells]
        except ValueError:
            raise OutputError(f"{path.name} line {lineno}: not a number in {ln[:80]!r}") from None
    rows = data.shape[0]
    t = data[:, 0]
    if not np.all(np.isfinite(t)):
        raise OutputError(f"{path.name}: a time is not finite (line {int(np.argmin(np.isfinite(t))) + 2})")
    tol = _time_tol(h, t, t_eval, t0 + ns * h)
    if rows == t_eval.size:
        expected = t_eval
        pick = np.arange(rows)
    elif rows == ns + 1:
        expected = t0 + h * np.arange(ns + 1)
        expected[-1] = t0 + ns * h
        pick = np.rint((t_eval - t0) / h).astype(np.int64)
    else:
        raise OutputError(f"{path.name} has {rows} rows; expected n_steps + 1 = {ns + 1} (every step) or "
                          f"len(t_eval) = {t_eval.size} (the output times)")
    bad = np.flatnonzero(np.abs(t - expected) > tol)
    if bad.size:
        i = int(bad[0])
        raise OutputError(f"{path.name} line {i + 2}: t = {t[i]!r}, expected {expected[i]!r} (row {i} of "
                          f"{'the output times' if rows == t_eval.size else 'the step grid t0 + i h'}; "
                          f"tolerance {tol:.3g} s)")
    return t_eval.copy(), data[pick, 1:].T.copy()


def _read_stats(path: Path) -> int | None:
    raw = _read_regular(path, _STATS_MAX)
    if raw is None:
        return None
    try:
        stats = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        raise OutputError(f"{path.name} is not JSON") from None
    nfev = stats.get("nfev") if isinstance(stats, dict) else None
    if isinstance(nfev, float) and nfev.is_integer():
        nfev = int(nfev)
    if isinstance(nfev, bool) or not isinstance(nfev, int) or nfev < 0:
        raise OutputError(f"{path.name}: `nfev` must be an integer >= 0, got {nfev!r:.40}")
    return nfev


def _remove_workdir(workdir: Path, ident: tuple) -> tuple[tuple, str]:
    """Empty and remove the run's directory (see the module docstring);
    returns (left-over names, a note or '')."""
    try:
        st = os.lstat(workdir)
    except FileNotFoundError:
        return (), f"the work directory {workdir} was gone after the run"
    if not stat.S_ISDIR(st.st_mode) or (st.st_dev, st.st_ino) != ident:
        return (), f"the work directory {workdir} was replaced during the run; left in place"
    names = sorted(os.listdir(workdir))
    leftovers = tuple(n for n in names if n not in (PROBLEM_FILE, TRAJECTORY_FILE, STATS_FILE))
    kept = []
    for name in names:
        p = workdir / name
        try:
            if stat.S_ISDIR(os.lstat(p).st_mode):
                if shutil.rmtree.avoids_symlink_attacks:
                    shutil.rmtree(p)
                else:  # pragma: no cover - platforms without fd-based rmtree
                    kept.append(name)
            else:
                os.unlink(p)  # a file, or a symbolic link (the link, never its target)
        except OSError:
            kept.append(name)
    if kept:
        return leftovers, f"could not remove {kept[:5]} from {workdir}; left in place"
    try:
        os.rmdir(workdir)
    except OSError as e:
        return leftovers, f"could not remove {workdir} ({e.strerror or e})"
    return leftovers, ""


def run_command(argv, problem: dict, *, timeout: float = DEFAULT_TIMEOUT) -> CommandResult:
    """Run the command ``argv`` on ``problem`` (see the module docstring).

    Parameters
    ----------
    argv : list of str
        The command line, with the placeholders ``{problem}``,
        ``{trajectory}``, ``{workdir}``, ``{thesis_code}``.
    problem : dict
        A protocol-1 problem (written as ``problem.json``).
    timeout : float
        Seconds before the program is killed (status "failed").

    Returns
    -------
    CommandResult
        Never raises for the program's failures.

    Raises
    ------
    ValueError
        ``argv`` or ``problem`` is malformed, or ``problem`` is not strict JSON.
    """
    check_problem(problem)
    if not (isinstance(timeout, (int, float)) and timeout > 0):
        raise ValueError(f"`timeout` must be a number > 0 (s), got {timeout!r}")
    text = json.dumps(problem, allow_nan=False, indent=1)
    n_state = 2 * problem["n_dof"]
    empty = (np.empty(0), np.empty((n_state, 0)))
    workdir = Path(tempfile.mkdtemp(prefix="rk4h-command-"))
    st = os.lstat(workdir)
    ident = (st.st_dev, st.st_ino)
    paths = {"problem": workdir / PROBLEM_FILE, "trajectory": workdir / TRAJECTORY_FILE, "workdir": workdir}
    result = None
    try:
        args = expand_argv(argv, **paths)
        missing = _program_missing(args[0])
        if missing:
            result = CommandResult(*empty, None, 0.0, "unavailable", missing, args)
            return result
        fd = os.open(paths["problem"], os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
            start = time.perf_counter()
            try:
                proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=out, stderr=err, cwd=workdir,
                                        start_new_session=True, close_fds=True)
            except FileNotFoundError:
                result = CommandResult(*empty, None, 0.0, "unavailable", _program_missing(args[0]) or
                                       f"{args[0]} not found", args)
                return result
            except OSError as e:
                result = CommandResult(*empty, None, 0.0, "failed", f"{args[0]} could not be started: "
                                       f"{e.strerror or e}", args)
                return result
            timed_out = False
            try:
                rc = proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                timed_out = True
                try:
                    os.killpg(proc.pid, signal.SIGKILL)  # its own session: the program and its children
                except OSError:
                    proc.kill()
                rc = proc.wait()
            wall = time.perf_counter() - start
            so, se = _tail(out), _tail(err)
        common = dict(argv=args, returncode=rc, stdout=so, stderr=se)
        if timed_out:
            result = CommandResult(*empty, None, wall, "failed",
                                   f"{args[0]} timed out after {timeout:g} s (killed)", **common)
        elif rc != 0:
            how = f"was killed by signal {-rc}" if rc < 0 else f"exited with status {rc}"
            result = CommandResult(*empty, None, wall, "failed", f"{args[0]} {how}: {_last_line(se, so)}",
                                   **common)
        else:
            try:
                t, y = read_trajectory(paths["trajectory"], problem)
                nfev = _read_stats(workdir / STATS_FILE)
            except OutputError as e:
                result = CommandResult(*empty, None, wall, "failed", f"{args[0]}: {e}", **common)
            else:
                result = CommandResult(t, y, nfev, wall, "ok", "", **common)
        return result
    finally:
        leftovers, note = _remove_workdir(workdir, ident)
        if result is not None:
            result.leftovers = leftovers
            if note:
                result.message = f"{result.message}; {note}" if result.message else note
