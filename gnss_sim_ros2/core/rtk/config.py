"""rtkrcv configuration: a generated one, or a user's own file with its options kept.

An rtkrcv options file (RTKLIB 2.4.3 manual, appendix C; rtkrcv.c ``rcvopts``
and options.c ``sysopts``) is ``key = value  # comment`` lines.  This module
reads one (:func:`read_conf`), builds the default RTK setup of the simulator
(:func:`default_options`) and writes the file rtkrcv runs with
(:func:`write_conf`).

A user's file keeps every option except the ones the node must own
(:data:`OWNED_KEYS`): the input streams (rover, base, correction), the
output streams and the log streams, which the node connects to its own TCP
ports, and the output format fields the node parses (llh or enu, GPST week/TOW,
degrees, velocity on, blank separator).  Those override the file's values,
and :func:`merge_options` says which ones it replaced.
"""
from __future__ import annotations

import re
from pathlib import Path

#: options of the input/output/log streams (rtkrcv.c rcvopts): always set by the node
STREAM_KEYS = tuple(f"inpstr{i}-{f}" for i in (1, 2, 3) for f in ("type", "path", "format")) + tuple(
    f"outstr{i}-{f}" for i in (1, 2) for f in ("type", "path", "format")) + tuple(
    f"logstr{i}-{f}" for i in (1, 2, 3) for f in ("type", "path"))
#: solution output format the node parses (options.c sysopts "out-*")
FORMAT_OPTIONS = {"out-solformat": "llh", "out-outhead": "off", "out-outopt": "off", "out-outvel": "on",
                  "out-timesys": "gpst", "out-timeform": "tow", "out-timendec": "3", "out-degform": "deg",
                  "out-fieldsep": "", "out-height": "ellipsoidal", "out-nmeaintv1": "0", "out-nmeaintv2": "0"}
OWNED_KEYS = STREAM_KEYS + tuple(FORMAT_OPTIONS)

#: pos1-navsys bit of each system (options.c NAVOPT: 1 gps, 4 glo, 8 gal, 16 qzs, 32 bds, 64 navic)
NAVSYS_BITS = {"G": 1, "R": 4, "E": 8, "J": 16, "C": 32, "I": 64}

_KEY_RE = re.compile(r"^[a-z0-9_-]+$")


class RtkConfigError(ValueError):
    """An rtkrcv options file or option value that cannot be used."""


def read_conf(path) -> dict[str, str]:
    """Options of an rtkrcv .conf file in file order ({key: value}, comments dropped)."""
    p = Path(path)
    try:
        text = p.read_text(errors="replace")
    except OSError as exc:
        raise RtkConfigError(f"rtkrcv options file {p}: cannot read it ({exc.strerror}) "
                             f"(parameter rtkrcv_conf)") from None
    out: dict[str, str] = {}
    for n, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if "=" not in line:
            raise RtkConfigError(f"{p}, line {n}: {raw.strip()!r} is not 'key = value' (rtkrcv options file)")
        key, value = (s.strip() for s in line.split("=", 1))
        if not _KEY_RE.match(key):
            raise RtkConfigError(f"{p}, line {n}: option name {key!r} is not an rtkrcv option name")
        out[key] = value
    if not out:
        raise RtkConfigError(f"{p}: no options (an rtkrcv options file has 'key = value' lines)")
    return out


#: positioning modes of the generated setup (options.c MODOPT)
MODES = ("kinematic", "static", "movingbase")


def default_options(systems: str = "GE", frequencies: int = 2, elevation_mask_deg: float = 10.0,
                    ratio_threshold: float = 3.0, mode: str = "kinematic") -> dict[str, str]:
    """The simulator's RTK setup: kinematic, continuous ambiguity resolution with the ratio test,
    broadcast ionosphere and Saastamoinen troposphere, dynamics on (velocity states: the ENU velocity
    output), base position from its RTCM 1005/1006 message.

    ``mode`` "movingbase": the base moves (RTKLIB takes its position from its own single point
    solution each epoch and needs base and rover observations of the same epoch, rtkpos.c TTOL_MOVEB).
    No baseline length constraint (pos2-baselen): with it RTKLIB 2.4.3 b34 lost the fix after a minute
    on a 1.2 m baseline of ours that it fixes throughout without (test_rtk_engine).

    Left at RTKLIB 2.4.3's defaults: pos2-arlockcnt 0, pos2-arelmask 0, pos2-maxout 5 epochs,
    pos2-rejionno 30 m, pos1-snrmask off.  On the demo path fix-and-hold (pos2-armode) helps some noise
    draws and not others (docs/VALIDATION.md "RTK"), so continuous stays."""
    if mode not in MODES:
        raise RtkConfigError(f"rtk mode {mode!r}: one of {MODES} (parameter rtk_mode)")
    bad = [s for s in systems if s not in NAVSYS_BITS]
    if bad or not systems:
        raise RtkConfigError(f"rtk systems {systems!r}: letters of {''.join(NAVSYS_BITS)} (parameter rtk_systems)")
    if frequencies not in (1, 2, 3):
        raise RtkConfigError(f"rtk frequencies = {frequencies!r}: 1, 2 or 3 (parameter rtk_frequencies)")
    if not ratio_threshold >= 1.0:
        raise RtkConfigError(f"ratio threshold = {ratio_threshold!r}: >= 1 (parameter rtk_ratio_threshold)")
    opts = {
        "pos1-posmode": mode,
        "pos1-frequency": {1: "l1", 2: "l1+2", 3: "l1+2+3"}[frequencies],   # options.c FRQOPT
        "pos1-soltype": "forward",
        "pos1-elmask": f"{float(elevation_mask_deg):g}",
        "pos1-dynamics": "on",
        "pos1-ionoopt": "brdc",
        "pos1-tropopt": "saas",
        "pos1-sateph": "brdc",
        "pos1-navsys": str(sum(NAVSYS_BITS[s] for s in dict.fromkeys(systems))),
        "pos2-armode": "continuous",
        "pos2-gloarmode": "off",
        "pos2-arthres": f"{float(ratio_threshold):g}",
        "pos2-maxage": "30",
        "ant2-postype": "rtcm",
        "misc-svrcycle": "10",
        "misc-timeout": "10000",
        "misc-reconnect": "1000",
    }
    if mode == "movingbase":
        opts["pos1-dynamics"] = "off"           # the base's own motion is not in rtkrcv's dynamics model
        opts.pop("ant2-postype")
    return opts


def merge_options(user: dict[str, str] | None, owned: dict[str, str],
                  defaults: dict[str, str] | None = None) -> tuple[dict[str, str], list[str]]:
    """(options rtkrcv runs with, user keys replaced): defaults, then the user's file, then the owned
    stream/format options over both."""
    out = dict(defaults or {})
    replaced = []
    for k, v in (user or {}).items():
        out[k] = v
    for k, v in owned.items():
        if user is not None and k in user and user[k] != v:
            replaced.append(k)
        out[k] = v
    return out, replaced


def write_conf(path, options: dict[str, str]) -> Path:
    """An rtkrcv options file (``key=value`` per line)."""
    p = Path(path)
    lines = ["# written by gnss_sim (core/rtk/config.py)"]
    for k, v in options.items():
        if "\n" in str(v) or "#" in str(v):
            raise RtkConfigError(f"rtkrcv option {k} = {v!r}: a value cannot hold '#' or a line break")
        lines.append(f"{k:<18}={v}")
    p.write_text("\n".join(lines) + "\n")
    return p
