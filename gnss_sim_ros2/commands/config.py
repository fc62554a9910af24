"""``gnss-sim config``: print the default parameter file, or check one."""
from __future__ import annotations

import sys


def add_arguments(parser):
    parser.add_argument("--check", metavar="FILE", help="validate a parameter file and print the merged values")


def run(args) -> int:
    import yaml

    from gnss_sim_ros2.parameters import default_config_yaml, load_config

    if args.check:
        try:
            cfg = load_config(args.check)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        print(yaml.safe_dump(cfg.ros_parameter_file_dict(), sort_keys=False), end="")
        return 0
    print(default_config_yaml(), end="")
    return 0
