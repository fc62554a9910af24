"""One module per `gnss-sim` subcommand (``add_arguments(parser)``, ``run(args)``), and what they share."""
import sys


def parse_triple(text: str, what: str) -> list[float]:
    """Three comma-separated numbers (``X,Y,Z``); ValueError naming the option ``what``."""
    try:
        vals = [float(v) for v in text.split(",")]
        if len(vals) != 3:
            raise ValueError
    except ValueError:
        raise ValueError(f"{what} needs three comma-separated numbers, got {text!r}") from None
    return vals


def fail(command: str, exc: Exception) -> int:
    """``gnss-sim COMMAND: error: EXC`` on stderr, one line; the exit code: 1 when another run holds the output folder
    (core/output_folder.OutputBusy: try again later), 2 for a bad input or a folder that is not ours."""
    from gnss_sim_ros2.core.output_folder import OutputBusy

    print(f"gnss-sim {command}: error: {exc}", file=sys.stderr)
    return 1 if isinstance(exc, OutputBusy) else 2


#: help of --world-offset (calibrate, compare, skyplot): the visibility parameter world_offset_enu_m
WORLD_OFFSET_HELP = ("a known georeference error applied on purpose: the world moved by east, north, up [m] "
                     "(parameter world_offset_enu_m, core/visibility/world_offset.py; compare --fit-offset reports "
                     "(e, n): give -e,-n,0); printed when set")


def check_scene_options(args) -> None:
    """calibrate / compare: ValueError naming the option for --world-offset without a scene to move (it was
    ignored without a word) and a --strong-cn0-dbhz that is not a C/N0 (NaN made every signal weak)."""
    import math

    if getattr(args, "world_offset", None) and not (getattr(args, "world", None) or getattr(args, "mesh", None)):
        raise ValueError("option --world-offset moves the scene of --world / --mesh, and neither is given")
    strong = getattr(args, "strong_cn0_dbhz", None)
    if strong is not None and not (math.isfinite(strong) and 0.0 <= strong <= 100.0):
        raise ValueError(f"option --strong-cn0-dbhz is {strong}: a C/N0 in 0..100 dB-Hz is needed")


def world_offset_scene(scene, text):
    """``scene`` moved by ``--world-offset E,N,U`` (None or empty: unchanged), checked by the parameter table as
    world_offset_enu_m (errors name the option) and printed on stderr, never applied silently."""
    if not text:
        return scene
    from gnss_sim_ros2.core.visibility.world_offset import is_zero, offset_note, shifted_scene
    from gnss_sim_ros2.parameters import validate_node

    off = parse_triple(text, "option --world-offset (east,north,up [m])")
    # where: the command line (the caller names the command; "gnss-sim calibrate" was said twice)
    validate_node("visibility", {"world_offset_enu_m": off}, "command line", {"world_offset_enu_m": "--world-offset"})
    if not is_zero(off):
        print(offset_note(off), file=sys.stderr)
    return shifted_scene(scene, off, "option --world-offset")
