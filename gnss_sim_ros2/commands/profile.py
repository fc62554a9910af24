"""``gnss-sim profile``: the receiver profiles (core/receiver/profiles.py, docs/PROFILES.md).

    gnss-sim profile list                 # the built-in profiles, one line each
    gnss-sim profile show NAME|FILE       # a profile as YAML with every default filled in
    gnss-sim profile show ublox_f9p > my_receiver.yaml    # a start for one's own, then --profile my_receiver.yaml
"""
from __future__ import annotations

import sys


def add_arguments(parser):
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    sub.add_parser("list", help="the built-in profiles: name, description")
    show = sub.add_parser("show", help="a profile as YAML with every default filled in (a start for your own)")
    show.add_argument("profile", metavar="NAME|FILE",
                      help="a built-in name or a profile YAML file (relative to the working directory)")


def run(args) -> int:
    from gnss_sim_ros2.core.receiver.profiles import builtin_names, load_profile, profile_yaml

    try:
        if args.action == "list":
            names = builtin_names()
            width = max(len(n) for n in names)
            for name in names:
                print(f"{name:<{width}}  {load_profile(name).description}")
            return 0
        text = profile_yaml(args.profile)
    except ValueError as exc:
        print(f"gnss-sim profile: error: {exc}", file=sys.stderr)
        return 2
    prof = load_profile(args.profile)
    print(f"# receiver profile {prof.name} ({prof.path}) with every default filled in: `gnss-sim simulate "
          f"--profile FILE` takes it\n# after edits; docs/PROFILES.md describes each key")
    print(text, end="")
    return 0
