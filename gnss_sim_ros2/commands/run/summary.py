"""What ``gnss-sim run`` writes at its end: summary.json and summary.md (satellites tracked, fix availability,
horizontal error against the true antenna, latencies; per robot and the worst one; the processes, the bag), the
RTK and heading figures with rtk_timeline.csv (core/rtk/summary.py), and skyplot.png of the last epoch."""
from __future__ import annotations

import numpy as np

from gnss_sim_ros2.commands.run.launcher import LAYOUT_MODES
from gnss_sim_ros2.core.metrics import p95, rms, rounded

#: figures of the worst robot: the lowest (min) or highest (max) value among the robots
WORST_BY = {"fix_availability": min, "horizontal_error_rms_m": max, "latency_ms_median": max,
            "latency_ms_p95": max, "latency_ms_p99": max, "epochs_without_output": max}


def run_summary(runner, n_epochs, dropped, wall_s, period) -> dict:
    """summary.json of a run (runner.Runner: its outputs, output folder, options, processes, recorder)."""
    out_dir, args = runner.out, runner.args
    robots = runner.outputs.robots
    per_robot = [r.samples(runner.outputs.probe) for r in robots]
    pooled = {key: [x for one in per_robot for x in one[key]] for key in per_robot[0]}
    n = len(robots)
    pooled_figures = figures(pooled, n_epochs * n)
    rinex = sorted(str(p.relative_to(out_dir)) for p in out_dir.glob("*.rnx"))
    if n > 1:
        rinex += sorted(str(p.relative_to(out_dir)) for p in out_dir.glob("robot*/*.rnx"))
    out = {
        "epochs": n_epochs, "epochs_without_output": dropped, "wall_s": round(wall_s, 3),
        "realtime_factor": round(n_epochs * period / wall_s, 2) if wall_s > 0 else None,
        **pooled_figures,
        "mode": LAYOUT_MODES[args.layout],
        "executor": runner.launcher.executor_name,
        "processes": runner.process_figures,
        "ros_domain_id": runner.domain_id,
        "foreign_publishers": runner.foreign,
        "satellite_states_publishers": runner.states_publishers,
        "pace": "realtime" if args.realtime else "as fast as the chain answers",
        "rinex_files": rinex,
        "configure_wall_s": round(runner.configure_wall_s, 3) if runner.configure_wall_s is not None else None,
        "peak_rss_mb": round(runner.peak_rss_mb, 1) if runner.peak_rss_mb is not None else None,
    }
    if n > 1:
        from gnss_sim_ros2.core.visibility import SCENE_LOADS

        out["robots"] = n
        out["scene_loads"] = dict(SCENE_LOADS)     # this process's: one world for every composed robot
        out["per_robot"] = {r.name: {"epochs_without_output": n_epochs - r.epochs_answered(n_epochs, period),
                                     **figures(one, n_epochs)}
                            for r, one in zip(robots, per_robot)}
        out["worst_robot"] = worst(out["per_robot"])
    if args.rtk:
        out.update(rtk_summary(runner.outputs, runner.cfg, out_dir, n_epochs, period))
    if runner.recorder is not None:
        from gnss_sim_ros2.recorder import count_messages

        out["bag"] = "bag"      # relative: the folder is moved into place at the end
        out["bag_messages"] = count_messages(out_dir / "bag")
    return out


def rtk_summary(outputs, cfg, out_dir, n_epochs: int, period: float) -> dict:
    """RTK figures: epochs with a /gnss/rtk/fix, fixed / float / single shares, horizontal error against the
    true antenna path (fixed solutions; every solution), and the time line (rtk_timeline.csv)."""
    from gnss_sim_ros2.core.rtk.summary import rtk_figures

    truth = {int(round(t / period)): x for t, x in outputs.truth.items()}
    rows = []
    for t, f in sorted(outputs.rtk_fix.items()):
        k = int(round(t / period))
        if not 0 <= k < n_epochs or k not in truth:
            continue
        quality = outputs.rtk_quality.get(round(t * 1e6), "unknown")
        rows.append((k * period, quality, f.latitude, f.longitude, f.altitude, truth[k]))
    rtk, timeline = rtk_figures(rows, n_epochs, period)
    lat = outputs.rtk_latency_s
    rtk["rtk_latency_ms_median"] = round(1e3 * float(np.median(lat)), 2) if lat else None
    rtk["rtk_latency_ms_p95"] = round(1e3 * float(np.percentile(lat, 95)), 2) if lat else None
    (out_dir / "rtk_timeline.csv").write_text(timeline)
    if cfg.node("receiver")["antenna2_frame"]:
        rtk.update(heading_summary(outputs, n_epochs, period, truth))
    return rtk


def heading_summary(outputs, n_epochs: int, period: float, truth: dict) -> dict:
    """Moving baseline: headings against the true baseline first -> second antenna."""
    from gnss_sim_ros2.core.rtk.summary import heading_figures

    truth2 = {int(round(t / period)): x for t, x in outputs.truth2.items()}
    rows = []
    for t, m in sorted(outputs.heading.items()):
        k = int(round(t / period))
        if not 0 <= k < n_epochs or k not in truth or k not in truth2:
            continue
        yaw_enu_deg = float(np.degrees(2.0 * np.arctan2(m.orientation.z, m.orientation.w)))
        sd_deg = float(np.degrees(np.sqrt(max(m.orientation_covariance[8], 0.0))))
        rows.append((k * period, outputs.heading_quality.get(round(t * 1e6), "unknown"), 90.0 - yaw_enu_deg,
                     sd_deg, truth[k], truth2[k]))
    return heading_figures(rows, n_epochs)


def antenna_world_m(vis_msg):
    """The antenna in the world frame of a gnss_sim_msgs/Visibility (None: no message)."""
    m = vis_msg
    return None if m is None else np.array([m.antenna_world_m.x, m.antenna_world_m.y, m.antenna_world_m.z])


def local_sky(local_nodes, vis_msg):
    """The sky grid at the last antenna position from the visibility node of this process (composed mode); None
    when the nodes run in other processes."""
    at = antenna_world_m(vis_msg)
    scenes = [node.scene for node in local_nodes if getattr(node, "scene", None) is not None]
    return scenes[0].sky_grid(at) if at is not None and scenes else None


def sky_plot(out_dir, cfg, vis_msg, sky=None):
    """skyplot.png of the last epoch (``vis_msg``, the last gnss_sim_msgs/Visibility); ``sky``: what the casts
    find (Scene.sky_grid) if known, else the scene is loaded here (nodes in other processes)."""
    m = vis_msg
    if m is None:
        return
    from gnss_sim_ros2.core.skyplot import plot_skyplot

    at = antenna_world_m(m)
    if sky is None:
        from gnss_sim_ros2.core.scene.demo_world import demo_world_path
        from gnss_sim_ros2.core.visibility import VisibilityOptions, load_scene

        vis = cfg.node("visibility")
        world = vis["world_file"] if vis["world_file"] or vis["mesh_file"] else str(demo_world_path())
        sky = load_scene(world, vis["mesh_file"], vis["materials_file"],
                         VisibilityOptions.from_params(vis)).sky_grid(at)
    sats = m.satellites
    plot_skyplot(out_dir / "skyplot.png", [s.sv for s in sats], np.array([s.azimuth_deg for s in sats]),
                 np.array([s.elevation_deg for s in sats]), np.array([s.state for s in sats]),
                 sky=sky, mask_deg=cfg.node("receiver")["elevation_mask_deg"],
                 title=f"last epoch, antenna at E {at[0]:.1f} N {at[1]:.1f} U {at[2]:.1f} m")


def summary_markdown(s: dict) -> str:
    lines = ["# gnss_sim run summary", "", "| figure | value |", "|---|---|"]
    for k, v in s.items():
        if k == "bag_messages":
            v = ", ".join(f"{t}: {n}" for t, n in sorted(v.items()))
        if k == "per_robot":
            continue
        lines.append(f"| {k} | {v} |")
    if "per_robot" in s:
        cols = list(next(iter(s["per_robot"].values())))
        lines += ["", "| robot | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
        lines += [f"| {name} | " + " | ".join(str(f[c]) for c in cols) + " |" for name, f in s["per_robot"].items()]
    return "\n".join(lines) + "\n"


def figures(x: dict, n_epochs: int) -> dict:
    """The run's figures from RobotOutputs.samples (of one robot, or pooled over several)."""
    tracked, err, lat_ms = x["tracked"], x["err"], x["lat_ms"]

    def r(v, nd=3):
        return round(float(v), nd)

    return {
        "satellites_tracked_mean": r(np.mean(tracked), 2) if tracked else 0,
        "satellites_tracked_min": int(min(tracked)) if tracked else 0,
        "satellites_tracked_max": int(max(tracked)) if tracked else 0,
        "fix_availability": round(len(x["fixes"]) / max(n_epochs, 1), 4),
        "horizontal_error_rms_m": rounded(rms(err), 3),
        "horizontal_error_p95_m": rounded(p95(err), 3),
        "latency_ms_median": r(np.median(lat_ms)) if lat_ms else None,
        "latency_ms_p95": r(np.percentile(lat_ms, 95)) if lat_ms else None,
        "latency_ms_p99": r(np.percentile(lat_ms, 99)) if lat_ms else None,
        # states published -> NavSatFix published (the fix follows the observations: ReceiverChain.finish)
        "fix_latency_ms_median": r(np.median(x["fix_lat_ms"])) if x["fix_lat_ms"] else None,
        "fix_latency_ms_p99": r(np.percentile(x["fix_lat_ms"], 99)) if x["fix_lat_ms"] else None,
    }


def worst(per_robot: dict) -> dict:
    """{figure: {"robot": name, "value": v}} of the worst robot per figure (WORST_BY)."""
    out = {}
    for key, pick in WORST_BY.items():
        have = {name: f[key] for name, f in per_robot.items() if f.get(key) is not None}
        if have:
            name = pick(have, key=have.get)
            out[key] = {"robot": name, "value": have[name]}
    return out
