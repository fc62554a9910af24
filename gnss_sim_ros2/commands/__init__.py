"""One module per `gnss-sim` subcommand (``add_arguments(parser)``, ``run(args)``), and what they share."""


def parse_triple(text: str, what: str) -> list[float]:
    """Three comma-separated numbers (``X,Y,Z``); ValueError naming the option ``what``."""
    try:
        vals = [float(v) for v in text.split(",")]
        if len(vals) != 3:
            raise ValueError
    except ValueError:
        raise ValueError(f"{what} needs three comma-separated numbers, got {text!r}") from None
    return vals
