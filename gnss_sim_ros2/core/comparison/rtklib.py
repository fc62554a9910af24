"""RTKLIB rnx2rtkp single point solutions, and the observation copy RTKLIB 2.4.3 reads correctly."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np

from ..rinex.obs_table import match_epochs
from .spp import Solutions

#: RTKLIB pos1-navsys bits (rtklib.h SYS_GPS 1, SYS_GLO 4, SYS_GAL 8, SYS_QZS 16, SYS_CMP 32, SYS_IRN 64)
RTKLIB_NAVSYS = {"G": 1, "R": 4, "E": 8, "J": 16, "C": 32, "I": 64}
#: RTKLIB solution time tags = epoch - receiver clock bias: matched to epochs within this [ns]
RTKLIB_TAG_NS = 50_000_000


#: BeiDou B1I observation codes whose tracking attribute RTKLIB 2.4.3 (b34, Debian's rnx2rtkp) mishandles:
#: measured on OPEC 2022-001, it applies the broadcast TGD1 (BDS-SIS-ICD-B1I 5.2.4.10) to "C2I" but not to
#: "C2X" (B1I, I+Q tracking, as a Trimble NETR9 labels it): zeroing TGD1 in the navigation file leaves its
#: solution from C2X unchanged to the last digit, and its BeiDou residuals per satellite follow c*TGD1
#: (2.3 m RMS, up to 5 m).  The attribute names the tracked channel, not another signal or group delay.
RTKLIB_BEIDOU_B1I_ALIASES = ("X", "Q")


def rtklib_observation_copy(obs_path, workdir) -> tuple[Path, list[str]]:
    """The observation file as RTKLIB 2.4.3 should read it: a copy in ``workdir`` whose BeiDou B1I codes
    with attribute X or Q (C2X, L2X, D2X, S2X; ...) are renamed to attribute I in the header's
    SYS / # / OBS TYPES (``RTKLIB_BEIDOU_B1I_ALIASES``), unless the file has a B1I code with attribute I.
    Returns (path, renamed codes); the original path and [] when nothing needs renaming or the file is
    not plain RINEX 3 text (compressed files are passed through unchanged)."""
    obs_path = Path(obs_path)
    try:
        with open(obs_path, encoding="ascii", errors="strict", newline="") as f:
            header = []
            for line in f:
                header.append(line)
                if line[60:].strip() == "END OF HEADER" or len(header) > 2000:
                    break
    except (UnicodeDecodeError, OSError):
        return obs_path, []
    if not header or header[0][60:].strip() != "RINEX VERSION / TYPE" or not header[0][:9].strip().startswith("3"):
        return obs_path, []
    rows = [i for i, ln in enumerate(header) if ln[60:].strip() == "SYS / # / OBS TYPES"]
    beidou, in_c = [], False
    for i in rows:
        if header[i][0] != " ":
            in_c = header[i][0] == "C"
        if in_c:
            beidou.append(i)
    fields = [(i, 7 + 4 * j) for i in beidou for j in range(13)]     # (line, column) of each code (A3, 1X)
    if any(header[i][c + 1: c + 3] == "2I" for i, c in fields):
        return obs_path, []          # B1I already tracked as I: RTKLIB prefers it, nothing to rename
    renamed = []
    for i, c in fields:
        code = header[i][c: c + 3]
        if len(code) == 3 and code[1] == "2" and code[2] in RTKLIB_BEIDOU_B1I_ALIASES:
            header[i] = header[i][:c] + code[:2] + "I" + header[i][c + 3:]
            renamed.append(code)
    if not renamed:
        return obs_path, []
    for i, line in enumerate(header):     # the phase shift records name the same codes
        if line[60:].strip() == "SYS / PHASE SHIFT" and line[:1] == "C" and line[2:5] in renamed:
            header[i] = line[:4] + "I" + line[5:]
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    out = workdir / obs_path.name
    if out.resolve() == obs_path.resolve():
        raise ValueError(f"{obs_path}: the RTKLIB copy would overwrite the original (choose another workdir)")
    with open(obs_path, encoding="ascii", newline="") as src, open(out, "w", encoding="ascii", newline="") as dst:
        for _ in header:
            src.readline()
        dst.writelines(header)
        for chunk in iter(lambda: src.read(1 << 20), ""):
            dst.write(chunk)
    return out, renamed


def rtklib_solutions(obs_path, nav_paths, systems: str, times: np.ndarray, workdir,
                     elevation_mask_deg: float = 10.0, options: dict | None = None) -> Solutions:
    """RTKLIB rnx2rtkp single point solutions (broadcast ionosphere, Saastamoinen) at ``times``;
    ``options``: further rnx2rtkp configuration lines (e.g. {"stats-eratio1": "10000"})."""
    if shutil.which("rnx2rtkp") is None:
        raise ValueError("solver 'rtklib': rnx2rtkp is not installed")
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    stem = Path(obs_path).name.replace(".", "_")
    conf = workdir / f"{stem}.conf"
    out = workdir / f"{stem}.pos"
    navsys = sum(RTKLIB_NAVSYS[s] for s in set(systems) if s in RTKLIB_NAVSYS)
    opts = {"pos1-posmode": "single", "pos1-elmask": f"{elevation_mask_deg:g}", "pos1-ionoopt": "brdc",
            "pos1-tropopt": "saas", "pos1-navsys": str(navsys), "out-solformat": "xyz", "out-timesys": "gpst",
            **(options or {})}
    conf.write_text("".join(f"{a}={b}\n" for a, b in opts.items()))
    obs_in, renamed = rtklib_observation_copy(obs_path, workdir / "input")
    note = (f"{Path(obs_path).name}: BeiDou {', '.join(renamed)} given to RTKLIB as attribute I (RTKLIB 2.4.3 "
            "applies TGD1 to C2I only)") if renamed else ""
    subprocess.run(["rnx2rtkp", "-k", str(conf), "-o", str(out), str(obs_in), *map(str, nav_paths)], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=600)
    t_sol, rows = [], []
    for ln in out.read_text().splitlines():
        if not ln.strip() or ln.startswith("%"):
            continue
        f = ln.split()
        t_sol.append(np.datetime64(f[0].replace("/", "-") + "T" + f[1], "ns"))
        rows.append((float(f[2]), float(f[3]), float(f[4]), int(f[6])))
    pos = np.full((len(times), 3), np.nan)
    used = np.zeros(len(times), dtype=int)
    if rows:
        # RTKLIB tags a solution with the receiver time corrected by its clock bias: match within 50 ms
        i_t, i_s = match_epochs(np.asarray(times), np.array(t_sol, dtype="datetime64[ns]"), RTKLIB_TAG_NS)
        arr = np.array(rows)
        pos[i_t] = arr[i_s, :3]
        used[i_t] = arr[i_s, 3].astype(int)
    return Solutions(pos, used, "RTKLIB rnx2rtkp", note)
