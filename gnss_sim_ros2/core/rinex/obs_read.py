"""RINEX observation files -> :class:`~gnss_sim_ros2.core.rinex.obs_table.ObsTable`: RINEX 3 and 4 bodies parsed here
(numpy on the fixed columns: a 24 h 30 s multi-GNSS file in seconds, with the LLI flags), RINEX 2 by georinex;
any compression georinex opens (gzip, Hatanaka .crx / .crx.gz, ...)."""
from __future__ import annotations

import io
import re
import warnings
from pathlib import Path

import numpy as np

from ..input_file import not_a_file
from .header import parse_obs_header
from .obs_table import ObsTable

_OBS_RE = re.compile(r"^[CLDS][0-9][A-Z]$")
_OBS2_RE = re.compile(r"^[CLDSP][0-9]$")


def rinex2_code(code: str, system: str) -> str:
    """RINEX 3 code of a RINEX 2 observation code for ``system`` (RINEX 3.04 section 5.1; RTKLIB rinex.c
    convcode): P1/P2 are P(Y) (attribute W, GLONASS P); C1 and band-1 L/D/S are C/A (C) for GPS, GLONASS,
    QZSS, SBAS; C2 is L2C (GPS, QZSS) or GLONASS C/A (C); band-2 L/D/S are P(Y) (GPS W, GLONASS P); every
    other band and system: attribute X (the RINEX 2 files do not say which)."""
    kind, band = ("C" if code[0] in "CP" else code[0]), code[1]
    if code[0] == "P" and band in "12":
        attr = "W" if system == "G" else "P"
    elif code == "C2":
        attr = "C" if system in "GJR" else "X"
    elif band == "1":
        attr = "C" if system in "GRJS" else "X"
    elif band == "2":
        attr = "W" if system == "G" else ("P" if system == "R" else "X")
    else:
        attr = "X"
    return kind + band + attr


def _rinex2_values(ds, svs: np.ndarray) -> dict[str, np.ndarray]:
    """RINEX 2 variables (C1, P2, L1, ...) as RINEX 3 codes, each system's columns under its own code."""
    sys_of = np.array([s[0] for s in svs.tolist()])
    values: dict[str, np.ndarray] = {}
    for v in ds.data_vars:
        if not _OBS2_RE.match(str(v)):
            continue
        a = np.asarray(ds[v].values, dtype=float)
        for system in np.unique(sys_of).tolist():
            cols = sys_of == system
            if not np.isfinite(a[:, cols]).any():
                continue
            code = rinex2_code(str(v), system)
            dst = values.setdefault(code, np.full(a.shape, np.nan))
            fill = cols[None, :] & np.isfinite(a) & ~np.isfinite(dst)   # C1 and P1 of one band: the first read
            dst[fill] = a[fill]
    return values


def _obs_types3(header_lines: list[str], path) -> dict[str, list[str]]:
    """SYS / # / OBS TYPES of a RINEX 3/4 header (continuation lines included): system -> codes."""
    out: dict[str, list[str]] = {}
    cur, n = None, 0
    for line in header_lines:
        if line[60:].strip() != "SYS / # / OBS TYPES":
            continue
        if line[0] != " ":
            cur = line[0]
            try:
                n = int(line[3:6])
            except ValueError:
                raise ValueError(f"{path}: unreadable SYS / # / OBS TYPES line {line[:60]!r}") from None
            out[cur] = []
        if cur is None:
            raise ValueError(f"{path}: SYS / # / OBS TYPES continuation without a system: {line[:60]!r}")
        out[cur] += line[7:60].split()
    for s, codes in out.items():
        del codes[n if s == cur else len(codes):]
    return out


def _fields_float(chars: np.ndarray) -> np.ndarray:
    """(N, w) ASCII bytes of F14.3 fields -> (N,) float, NaN where blank."""
    blank = np.all((chars == 32) | (chars == 0), axis=1)
    c = np.ascontiguousarray(chars)
    c[blank, -3:] = np.frombuffer(b"nan", np.uint8)
    c[c == 0] = 32
    return c.view(f"S{c.shape[1]}").ravel().astype(float)


def _rinex3_table(text: str, path, tlim) -> tuple:
    """(times, svs, values, lli) of the body of a RINEX 3/4 observation file, numpy on fixed columns
    (RINEX 3.05 section 5.6 / table A3: "> yyyy mm dd hh mm ss.sssssss  f nnn" epoch records, then one line per
    satellite: id A3 + per observation type F14.3, LLI I1, SSI I1).  Event records (flags 2-6) are skipped."""
    lines = text.splitlines()
    try:
        end = next(i for i, line in enumerate(lines) if line[60:].strip() == "END OF HEADER")
    except StopIteration:
        raise ValueError(f"{path}: no END OF HEADER") from None
    types = _obs_types3(lines[:end], path)
    t_list, rec_lines, rec_epoch = [], [], []
    lo = hi = None
    if tlim is not None:
        lo, hi = (np.datetime64(t, "ns") for t in tlim)
    i, n_lines = end + 1, len(lines)
    while i < n_lines:
        line = lines[i]
        if not line.startswith(">"):
            i += 1
            continue
        try:
            flag = int(line[31:32] or 0)
            n = int(line[32:35])
        except ValueError:
            raise ValueError(f"{path}, line {i + 1}: unreadable epoch record {line[:41]!r}") from None
        if flag > 1:                      # events (2-5: header records follow) and cycle-slip records (6)
            i += n + 1
            continue
        body = lines[i + 1:i + 1 + n]
        if len(body) < n or any(b.startswith(">") for b in body):    # a cut file or a miscounted record
            got = next((k for k, b in enumerate(body) if b.startswith(">")), len(body))
            cut = " before the end of the file (a truncated file?)" if got == len(body) else ""
            raise ValueError(f"{path}, line {i + 1}: the epoch record announces {n} satellites, {got} lines of "
                             f"them follow{cut}")
        try:
            y, mo, d, h, mi = (int(x) for x in line[2:29].split()[:5])
            sec = float(line[18:29])
        except ValueError:
            raise ValueError(f"{path}, line {i + 1}: unreadable epoch time {line[:29]!r}") from None
        ns = int(round(sec * 1e9))
        t = np.datetime64(f"{y:04d}-{mo:02d}-{d:02d}T{h:02d}:{mi:02d}", "ns") + np.timedelta64(ns, "ns")
        if (lo is None or t >= lo) and (hi is None or t <= hi):
            e = len(t_list)
            t_list.append(t)
            rec_lines += body
            rec_epoch += [e] * n
        i += n + 1
    times = np.array(t_list, dtype="datetime64[ns]")
    if not rec_lines:
        return times, np.zeros(0, "<U3"), {}, {}
    width = 3 + 16 * max(len(c) for c in types.values())
    buf = np.array(rec_lines, dtype=f"S{width}").view(np.uint8).reshape(len(rec_lines), width).copy()
    ids = buf[:, :3].copy()
    ids[ids[:, 1] == 32, 1] = ord("0")                      # "G 5" -> "G05"
    sv_all = ids.view("S3").ravel().astype("<U3")
    svs, col = np.unique(sv_all, return_inverse=True)
    epoch = np.asarray(rec_epoch)
    values: dict[str, np.ndarray] = {}
    lli: dict[str, np.ndarray] = {}
    for system, codes in types.items():
        rows = np.flatnonzero(buf[:, 0] == ord(system))
        if not len(rows):
            continue
        for k, code in enumerate(codes):
            if not _OBS_RE.match(code):
                continue
            a = 3 + 16 * k
            v = _fields_float(buf[rows, a:a + 14])
            dst = values.setdefault(code, np.full((len(times), len(svs)), np.nan))
            dst[epoch[rows], col[rows]] = v
            if code[0] == "L":
                flag = buf[rows, a + 14]
                f = np.where((flag >= 48) & (flag <= 57), flag - 48, 0).astype(np.int8)
                dl = lli.setdefault(code, np.zeros((len(times), len(svs)), np.int8))
                dl[epoch[rows], col[rows]] = f
    return times, svs, values, lli


def load_rinex(path, tlim=None) -> ObsTable:
    """RINEX 2, 3 or 4 observation file (plain, compressed or Hatanaka).  RINEX 3/4: :func:`_rinex3_table`
    (with the carrier phases' loss-of-lock indicators in ``ObsTable.lli``); RINEX 2 via georinex (its warnings
    silenced), its codes become RINEX 3 codes (:func:`rinex2_code`)."""
    from georinex.rio import opener  # plain, .gz, .Z, .bz2, .zip and Hatanaka (CRINEX, with the hatanaka package)

    path = Path(path)
    if (why := not_a_file(path)) is not None:
        raise ValueError(f"{path}: {why}")
    try:
        with opener(path) as f:
            text = f.read()
    except (OSError, EOFError, UnicodeDecodeError, ValueError) as exc:
        raise ValueError(f"{path}: cannot open as a RINEX observation file ({exc})") from None
    hdr = parse_obs_header(io.StringIO(text), path)
    if hdr["version"] >= 3:
        times, svs, values, lli = _rinex3_table(text, path, tlim)
        return ObsTable(times, svs, values, str(path), "rinex", hdr["approx"], hdr["glo"], lli=lli)
    import georinex as gr

    kw = {}
    if tlim is not None:
        kw["tlim"] = tuple(np.datetime_as_string(np.datetime64(t, "us")) for t in tlim)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = gr.load(path, **kw)
    except Exception as exc:  # noqa: BLE001  georinex raises many kinds
        raise ValueError(f"{path}: georinex could not read it: {exc}") from exc
    if "time" not in ds.dims or "sv" not in ds.dims:
        times, svs = np.zeros(0, "datetime64[ns]"), np.zeros(0, "<U3")
        values = {}
    else:
        times = ds.time.values.astype("datetime64[ns]")
        svs = np.asarray(ds.sv.values).astype("<U3")
        values = _rinex2_values(ds, svs)
    return ObsTable(times, svs, values, str(path), "rinex", hdr["approx"], hdr["glo"])
