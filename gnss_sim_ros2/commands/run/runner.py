"""One ``gnss-sim run`` from start to end, in order: the ROS side and the nodes (launcher), the run's
subscriptions (outputs), the bag, configure and activate, the epochs (clock), then the summary (summary) with the
processes' CPU and memory (process_stats), and the end of every node and process."""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from gnss_sim_ros2 import graph
from gnss_sim_ros2.commands.run.clock import ClockDriver
from gnss_sim_ros2.commands.run.launcher import LAYOUT_WORDS, Launcher
from gnss_sim_ros2.commands.run.outputs import RunOutputs
from gnss_sim_ros2.commands.run.process_stats import ProcessStats, proc_peak_rss_mb
from gnss_sim_ros2.commands.run.summary import local_sky, run_summary, sky_plot, summary_markdown


class Runner:
    def __init__(self, cfg, out: Path, params_file: Path, args):
        self.cfg, self.out, self.params_file, self.args = cfg, out, params_file, args
        self.launcher = Launcher(cfg, args, params_file)
        self.clock: ClockDriver | None = None
        self.outputs: RunOutputs | None = None
        self.stats: ProcessStats | None = None
        self.recorder = None
        self.started = False
        self.domain_id = None
        self.foreign: dict = {}
        self.states_publishers = None
        self.process_figures: dict = {}
        self.configure_wall_s = self.peak_rss_mb = None

    @property
    def epochs_done(self) -> int:
        return self.clock.epochs_done if self.clock is not None else 0

    def log(self, text: str):
        if not self.args.quiet:
            print(f"[gnss-sim run] {text}", file=sys.stderr, flush=True)

    @staticmethod
    def warn(text: str):
        """Printed even with --quiet."""
        print(f"[gnss-sim run] {text}", file=sys.stderr, flush=True)

    # ------------------------------------------------------------------ graph
    def start(self):
        self.launcher.init_ros()
        driver = self.launcher.driver
        self.clock = ClockDriver(driver, self.launcher.executor)
        self.outputs = RunOutputs(driver, self.cfg, self.args)
        self.clock.set_clock(0.0)
        if not self.args.no_record:
            from gnss_sim_ros2.recorder import BagRecorder

            self.recorder = BagRecorder(driver, self.out / "bag", graph.recorded(self.args.robots)
                                        + (graph.RECORDED_RTK if self.args.rtk else ()))
        self.launcher.start_nodes(self.specs())
        self.started = True

    def specs(self):
        """The nodes of this run (graph.nodes, and the RTK ones with --rtk)."""
        return (graph.nodes(not self.args.no_trajectory_player, self.args.robots, self.args.layout == "fleet")
                + (graph.rtk_nodes(self.cfg) if self.args.rtk else []))

    # ------------------------------------------------------------------ run
    def run(self, stop) -> int:
        from gnss_sim_ros2.nodes.manager import TransitionFailed

        eph = self.cfg.node("ephemeris")
        duration = eph["duration_s"]
        period = 1.0 / eph["rate_hz"]
        n_epochs = int(np.floor(duration / period + 1e-9)) + 1
        self.log(f"starting {LAYOUT_WORDS[self.args.layout]}; "
                 f"{n_epochs} epochs of {period:g} s; ROS_DOMAIN_ID={self.domain_id}; output {self.out}")
        try:
            self.start()
            if self.args.no_autostart:
                self.log("--no-autostart: waiting for another lifecycle manager (Ctrl-C to stop)")
                while not stop["flag"]:
                    self.clock.spin(0.1)
                return 0
            t_configure = time.perf_counter()
            self.launcher.manager.transition("configure")
            self.configure_wall_s = time.perf_counter() - t_configure
            self.peak_rss_mb = proc_peak_rss_mb(os.getpid())   # every node when composed
            self.log(f"{self.args.robots} robot(s) configured in {self.configure_wall_s:.2f} s (scene, ephemeris, "
                     f"receivers), peak memory of this process "
                     f"{'unknown' if self.peak_rss_mb is None else f'{self.peak_rss_mb:.0f} MB'}")
            self.launcher.manager.transition("activate")
        except TransitionFailed as exc:
            print(f"gnss-sim run: error: {exc}", file=sys.stderr)
            return 3
        self.clock.spin(0.3)  # let the recorder find the topics and TF static latch
        self.check_foreign_publishers()
        self.states_publishers = self.launcher.states_publishers()
        self.stats = ProcessStats(self.launcher.process_pids())
        self.stats.start()
        done = self.clock.drive(self.cfg, self.args, self.outputs, n_epochs, period, stop, self.log)
        if done.code:
            return done.code
        self.clock.spin(0.3)
        wall = time.perf_counter() - done.start_perf_s
        self.check_foreign_publishers()   # again: discovery of another process's node may take longer than 0.3 s
        self.process_figures = self.stats.figures(done.epochs)
        self.finish(done.epochs, done.dropped, wall, period)
        return 0

    def check_foreign_publishers(self):
        """Publishers on the run's topics that are not the graph's: warned once each, kept for the summary."""
        for topic, nodes in self.launcher.foreign_publishers().items():
            new = [n for n in nodes if n not in self.foreign.get(topic, [])]
            if new:
                self.foreign[topic] = sorted(self.foreign.get(topic, []) + new)
                self.warn(f"warning: {topic} has publishers outside this run's graph: {', '.join(new)}")

    def finish(self, n_epochs: int, dropped: int, wall_s: float, period: float):
        """Close the files (nodes cleaned up), then summary, sky plot and bag counts."""
        sky = local_sky(self.launcher.local, self.outputs.last_vis)    # before cleanup frees the node's scene
        self.launcher.shutdown_nodes(self.log)
        if self.recorder is not None:
            self.recorder.close()
        summary = run_summary(self, n_epochs, dropped, wall_s, period)
        (self.out / "summary.json").write_text(json.dumps(summary, indent=2))
        (self.out / "summary.md").write_text(summary_markdown(summary))
        sky_plot(self.out, self.cfg, self.outputs.last_vis, sky)
        print(summary_markdown(summary))

    def close(self):
        if not self.started:
            return
        try:
            self.launcher.shutdown_nodes(self.log)
        except Exception as exc:  # noqa: BLE001 - still close the bag and stop the processes
            self.log(f"shutdown: {exc}")
        if self.recorder is not None:
            self.recorder.close()
        self.launcher.stop_processes()
        self.launcher.destroy_local_nodes()
        self.outputs.close()
        self.launcher.close_ros()
        self.started = False
