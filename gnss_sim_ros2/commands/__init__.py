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
