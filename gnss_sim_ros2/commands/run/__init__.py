"""``gnss-sim run``: the running system, what ``ros2 launch gnss_sim sim.launch.py`` starts.

Builds the node graph of gnss_sim_ros2/graph.py (trajectory player, ephemeris,
visibility, receiver) with the parameters of one file, in this process
(composed), one process per robot (its player, visibility and receiver; the
ephemeris node here) or one process per node, brings every node through configure and
activate, drives the simulated clock (/clock) epoch by epoch as fast as the
chain answers (or at real-time pace), records a rosbag2 (MCAP) bag, and
writes into the output folder: RINEX observation and navigation files, the
bag, a sky plot PNG and a summary.

One module per concept: ``command`` (options, output folder and domain, the run's exit code), ``runner``
(the run's steps in order), ``launcher`` (process layouts: node processes and local nodes, their lifecycle),
``clock`` (the /clock loop), ``outputs`` (the subscriptions that read the run's outputs), ``summary``
(summary.json/.md, RTK figures, the sky plot), ``process_stats`` (/proc CPU and memory), ``isolation`` (the
ROS domain and the node processes' end with their parent).
"""
from gnss_sim_ros2.commands.run.command import add_arguments, run

__all__ = ["add_arguments", "run"]
