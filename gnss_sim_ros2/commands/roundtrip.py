"""``gnss-sim roundtrip``: every gnss_sim_msgs type from this process to another.

The parent publishes a filled sample of each type (reliable, transient-local
QoS); a child process started with ``--listen`` subscribes, and prints each
message it receives as one JSON line; the parent compares every field.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time

TOPIC_PREFIX = "/gnss_sim_roundtrip/"


def add_arguments(parser):
    parser.add_argument("--listen", action="store_true", help="(internal) run the receiving side")
    parser.add_argument("--timeout", type=float, default=30.0, help="seconds to wait for every message [30]")


def _qos():
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


#: longest wait of --timeout [s]
MAX_TIMEOUT_S = 3600.0


def _listen(timeout_s: float) -> int:
    import rclpy

    from gnss_sim_ros2.messages.samples import MESSAGE_TYPES, message_class, to_dict

    rclpy.init()
    node = rclpy.create_node("gnss_sim_roundtrip_listener")
    pending = set(MESSAGE_TYPES)

    def make_cb(name):
        def cb(msg):
            if name in pending:
                pending.discard(name)
                print(json.dumps({"type": name, "msg": to_dict(msg)}), flush=True)
        return cb

    subs = [node.create_subscription(message_class(n), TOPIC_PREFIX + n, make_cb(n), _qos()) for n in MESSAGE_TYPES]
    deadline = time.monotonic() + timeout_s
    while pending and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    del subs
    node.destroy_node()
    rclpy.shutdown()
    return 0 if not pending else 1


def _compare(expected, got, path=""):
    """List of differences between two dict views (floats compared exactly: no conversion happens)."""
    if isinstance(expected, dict):
        out = []
        for k in expected:
            out += _compare(expected[k], got.get(k) if isinstance(got, dict) else None, f"{path}.{k}")
        return out
    if isinstance(expected, list):
        if not isinstance(got, list) or len(got) != len(expected):
            return [f"{path}: {expected!r} != {got!r}"]
        return [d for i, (e, g) in enumerate(zip(expected, got)) for d in _compare(e, g, f"{path}[{i}]")]
    return [] if expected == got else [f"{path}: sent {expected!r}, received {got!r}"]


def run(args) -> int:
    if not 0 < args.timeout <= MAX_TIMEOUT_S:        # nan fails too; 0 or less: nothing could be received
        print(f"gnss-sim roundtrip: error: option --timeout is {args.timeout:g}; give seconds in "
              f"(0, {MAX_TIMEOUT_S:g}]", file=sys.stderr)
        return 2
    if args.listen:
        return _listen(args.timeout)

    import rclpy

    from gnss_sim_ros2.messages.samples import MESSAGE_TYPES, message_class, sample, to_dict

    child = subprocess.Popen(
        [sys.executable, "-m", "gnss_sim_ros2.cli", "roundtrip", "--listen", "--timeout", str(args.timeout)],
        stdout=subprocess.PIPE, text=True, env=os.environ.copy(),
    )
    rclpy.init()
    node = rclpy.create_node("gnss_sim_roundtrip_talker")
    sent = {}
    pubs = []
    for name in MESSAGE_TYPES:
        msg = sample(name)
        pub = node.create_publisher(message_class(name), TOPIC_PREFIX + name, _qos())
        pub.publish(msg)
        pubs.append(pub)
        sent[name] = to_dict(msg)
    received = {}
    try:
        # Keep the publishers alive (transient local) while the child reads.
        import selectors

        sel = selectors.DefaultSelector()
        sel.register(child.stdout, selectors.EVENT_READ)
        deadline = time.monotonic() + args.timeout + 5
        while len(received) < len(MESSAGE_TYPES) and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.0)
            if sel.select(timeout=0.1):
                line = child.stdout.readline()
                if not line:
                    break
                item = json.loads(line)
                received[item["type"]] = item["msg"]
    finally:
        child.wait(timeout=args.timeout + 10)
        node.destroy_node()
        rclpy.shutdown()

    failures = 0
    for name in MESSAGE_TYPES:
        if name not in received:
            print(f"{name}: NOT RECEIVED", file=sys.stderr)
            failures += 1
            continue
        diffs = _compare(sent[name], received[name], name)
        if diffs:
            failures += 1
            print(f"{name}: {len(diffs)} fields differ: " + "; ".join(diffs[:5]), file=sys.stderr)
        else:
            n = len(json.dumps(sent[name]))
            print(f"{name}: received in another process, every field equal ({n} chars of fields)")
    print(f"roundtrip: {len(MESSAGE_TYPES) - failures} of {len(MESSAGE_TYPES)} message types intact")
    return 1 if failures else 0
