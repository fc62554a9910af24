"""A node process that hangs after SIGINT (a callback or a cleanup that never returns) does not wait silently for
ros2 launch's SIGKILL: nodes/common.StopSignals dumps every thread's stack and exits 1 (test_launch_robot_layout once
saw a robot container ignore SIGINT and SIGTERM, exit -9, with no word of where it hung)."""
import signal
import subprocess
import sys
import time

CHILD = """
import sys, time
from gnss_sim_ros2.nodes import common
common.STOP_WATCHDOG_S = 1.0
stop = common.StopSignals()
print('ready', flush=True)
def stuck_in_cleanup():
    time.sleep(60)            # a cleanup that never returns: the flag is set, nobody looks at it
while not stop.stopped:
    time.sleep(0.01)
stuck_in_cleanup()
"""


def test_a_process_hung_after_sigint_says_where_and_exits():
    p = subprocess.Popen([sys.executable, "-c", CHILD], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "ready"
    t0 = time.monotonic()
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=30)
    assert p.returncode == 1, err
    assert time.monotonic() - t0 < 20
    assert "stuck_in_cleanup" in err, err
