#!/usr/bin/env python3
"""Soak benchmark of the dimr node (driven by scripts/soak.sh): replays a bag's /map_cloud
messages in a loop with monotonically increasing stamps under simulated time (this script
publishes /clock, `speedup` x faster than real time) for `sim_minutes` of simulated time, and
records per processed cloud the node's latency (cloud received -> scene built), processing time
and instance count, and from the node's diagnostics every 0.5 s its RSS, queue drops and
counters. Writes SOAK.json (samples + summary), SOAK.csv and SOAK.svg (latency and RSS over
simulated time, drawn by this script), and prints a table.

usage: soak.py BAG OUT_PREFIX [--sim-minutes 30] [--speedup 4] [--warmup-minutes 5]
Exit status 0 when it ran to the end (the goals are reported, not enforced)."""
import argparse
import json
import os
import platform
import statistics
import sys
import threading
import time

import rosbag
import rospy
from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2

from dimr.msg import SceneMeshes


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def cpu_seconds(pid):
    """utime + stime of process `pid` (all threads) in seconds, or nan."""
    try:
        with open("/proc/%d/stat" % pid) as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return float("nan")


def median(v):
    return statistics.median(v) if v else float("nan")


def svg_plot(path, scenes, diags, sim_minutes, warmup_s, title):
    """Two panels over simulated minutes: latency / processing (s) and node RSS (MB)."""
    w, h, ml, mr, mt, gap, ph = 900, 700, 70, 20, 40, 40, 170
    out = ['<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" '
           'font-family="sans-serif" font-size="12">' % (w, h),
           '<rect width="100%" height="100%" fill="white"/>',
           '<text x="%d" y="20" font-size="14">%s</text>' % (ml, title)]
    x_max = sim_minutes * 60.0

    def panel(top, series, y_label, y_min=None):
        vals = [v for _, pts, _ in series for _, v in pts]
        lo = min(vals) if y_min is None else y_min
        hi = max(vals) if vals else 1.0
        if hi <= lo:
            hi = lo + 1.0
        hi += 0.05 * (hi - lo)
        pw = w - ml - mr

        def X(t):
            return ml + pw * t / x_max

        def Y(v):
            return top + ph - ph * (v - lo) / (hi - lo)
        out.append('<rect x="%d" y="%d" width="%d" height="%d" fill="none" stroke="#444"/>'
                   % (ml, top, pw, ph))
        out.append('<rect x="%d" y="%d" width="%.1f" height="%d" fill="#eee"/>'
                   % (ml + 1, top + 1, X(warmup_s) - ml - 1, ph - 2))
        for i in range(5):
            v = lo + (hi - lo) * i / 4
            out.append('<line x1="%d" x2="%d" y1="%.1f" y2="%.1f" stroke="#ddd"/>'
                       % (ml, ml + pw, Y(v), Y(v)))
            out.append('<text x="%d" y="%.1f" text-anchor="end">%.3g</text>'
                       % (ml - 5, Y(v) + 4, v))
        for m in range(0, int(sim_minutes) + 1, 5):
            out.append('<text x="%.1f" y="%d" text-anchor="middle">%d</text>'
                       % (X(m * 60), top + ph + 15, m))
        out.append('<text x="15" y="%d" transform="rotate(-90 15 %d)" text-anchor="middle">'
                   '%s</text>' % (top + ph // 2, top + ph // 2, y_label))
        lx = ml + 10
        for name, pts, color in series:
            if pts:
                d = " ".join("%.1f,%.1f" % (X(t), Y(v)) for t, v in pts)
                out.append('<polyline fill="none" stroke="%s" stroke-width="1.5" points="%s"/>'
                           % (color, d))
            out.append('<text x="%d" y="%d" fill="%s">%s</text>' % (lx, top + 15, color, name))
            lx += 9 * len(name) + 20
    panel(mt, [("latency (cloud received -> scene built)",
                [(s["sim_s"], s["latency_s"]) for s in scenes], "#c03030"),
               ("processing", [(s["sim_s"], s["processing_s"]) for s in scenes], "#3060c0")],
          "seconds", 0.0)
    panel(mt + ph + gap, [("node RSS", [(d["sim_s"], d["rss_mb"]) for d in diags], "#208040")],
          "MB")
    panel(mt + 2 * (ph + gap), [("machine load (1-min average, 2 cores)",
                                 [(d["sim_s"], d["load1"]) for d in diags], "#806020")],
          "load", 0.0)
    out.append('<text x="%d" y="%d" text-anchor="middle">simulated time (min); grey: warm-up'
               '</text>' % (w // 2, mt + 3 * ph + 2 * gap + 35))
    out.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("bag")
    ap.add_argument("out")
    ap.add_argument("--sim-minutes", type=float, default=30.0)
    ap.add_argument("--speedup", type=float, default=4.0)
    ap.add_argument("--warmup-minutes", type=float, default=5.0)
    ap.add_argument("--node", default="/dimr")
    ap.add_argument("--node-pid", type=int, default=0,
                    help="process of the node (CPU time per reconstruction; 0 = not measured)")
    a = ap.parse_args()
    clouds = []
    with rosbag.Bag(a.bag) as bag:
        for _, msg, _ in bag.read_messages(topics=["/map_cloud"]):
            clouds.append(msg)
    if not clouds:
        print("soak: %s has no /map_cloud" % a.bag, file=sys.stderr)
        return 1
    t0 = clouds[0].header.stamp
    offsets = [(c.header.stamp - t0).to_sec() for c in clouds]
    period = offsets[-1] + max(offsets[-1] / max(len(offsets) - 1, 1), 0.2)  # one bag loop

    rospy.init_node("dimr_soak", anonymous=True, disable_signals=True)
    clock_pub = rospy.Publisher("/clock", Clock, queue_size=10)
    cloud_pub = rospy.Publisher("/map_cloud", PointCloud2, queue_size=2)
    lock = threading.Lock()
    scenes, diags = [], []
    sim_start = rospy.Time(t0.to_sec())
    wall_start = [None]

    def sim_now():
        return (time.time() - wall_start[0]) * a.speedup if wall_start[0] else 0.0

    def on_scene(m):
        if not m.input_points:
            return
        with lock:
            scenes.append({"sim_s": (m.header.stamp - sim_start).to_sec(),
                           "wall_s": time.time() - (wall_start[0] or time.time()),
                           "latency_s": m.latency, "processing_s": m.processing_time,
                           "instances": len(m.instances), "input_points": m.input_points})

    def on_diag(arr):
        for st in arr.status:
            if not st.name.endswith("reconstruction"):
                continue
            v = {kv.key: kv.value for kv in st.values}
            if "rss_mb" not in v or wall_start[0] is None:
                continue
            try:
                with open("/proc/loadavg") as f:
                    load = float(f.read().split()[0])
            except (OSError, ValueError):
                load = float("nan")
            with lock:
                diags.append({"sim_s": sim_now(), "rss_mb": float(v["rss_mb"]), "load1": load,
                              "node_cpu_s": cpu_seconds(a.node_pid) if a.node_pid else None,
                              "queue_drops": int(v.get("queue_drops", 0)),
                              "clouds_received": int(v.get("clouds_received", 0)),
                              "clouds_processed": int(v.get("clouds_processed", 0)),
                              "pipeline_errors": int(v.get("pipeline_errors", 0)),
                              "max_callback_ms": float(v.get("max_callback_ms", "nan")),
                              "compute": v.get("compute", "")})

    rospy.Subscriber("/scene_meshes", SceneMeshes, on_scene, queue_size=20)
    rospy.Subscriber("/diagnostics", DiagnosticArray, on_diag, queue_size=20)
    rospy.wait_for_service(a.node + "/reset", timeout=300)
    deadline = time.time() + 30
    while cloud_pub.get_num_connections() == 0 and time.time() < deadline:
        time.sleep(0.05)
    print("soak: %d map clouds per loop (%.1f s), %.0f simulated minutes at %.1fx -> %.1f wall"
          " minutes" % (len(clouds), period, a.sim_minutes, a.speedup,
                        a.sim_minutes / a.speedup), flush=True)
    wall_start[0] = time.time()
    total = a.sim_minutes * 60.0
    k, i, sent = 0, 0, 0
    next_report = 60.0
    while True:
        s = sim_now()
        if s >= total:
            break
        clock_pub.publish(Clock(clock=sim_start + rospy.Duration.from_sec(s)))
        due = k * period + offsets[i]
        if s >= due:
            c = clouds[i]
            c.header.stamp = sim_start + rospy.Duration.from_sec(due)
            cloud_pub.publish(c)
            sent += 1
            i += 1
            if i == len(clouds):
                i, k = 0, k + 1
        if s >= next_report:
            with lock:
                print("soak: %5.1f sim min, %d clouds sent, %d scenes, RSS %.0f MB" % (
                    s / 60, sent, len(scenes), diags[-1]["rss_mb"] if diags else 0), flush=True)
            next_report += 60.0 * max(1.0, a.sim_minutes / 15)
        time.sleep(0.01)
    time.sleep(3.0)  # last diagnostics
    wall = time.time() - wall_start[0]

    with lock:
        scenes_c, diags_c = list(scenes), list(diags)
    warm = a.warmup_minutes * 60.0
    post = [d for d in diags_c if d["sim_s"] >= warm]
    post_s = [s for s in scenes_c if s["sim_s"] >= warm]
    rss_warm = median([d["rss_mb"] for d in post[:max(1, len(post) // 10)]])
    rss_end = median([d["rss_mb"] for d in post[-max(1, len(post) // 10):]])
    third = max(1, len(post_s) // 3)
    lat_first = median([s["latency_s"] for s in post_s[:third]])
    lat_last = median([s["latency_s"] for s in post_s[-third:]])
    proc = [s["processing_s"] for s in post_s]
    wait = [s["latency_s"] - s["processing_s"] for s in post_s]
    last = diags_c[-1] if diags_c else {}
    summary = {
        "cpu": cpu_model(), "compute": last.get("compute", ""),
        "bag": os.path.abspath(a.bag), "sim_minutes": a.sim_minutes, "speedup": a.speedup,
        "wall_minutes": wall / 60.0, "warmup_minutes": a.warmup_minutes,
        "clouds_sent": sent, "clouds_received": last.get("clouds_received", 0),
        "clouds_processed": last.get("clouds_processed", 0),
        "queue_drops": last.get("queue_drops", 0),
        "pipeline_errors": last.get("pipeline_errors", 0),
        "scenes": len(scenes_c),
        "rss_mb_after_warmup": rss_warm, "rss_mb_end": rss_end,
        "rss_mb_max": max([d["rss_mb"] for d in diags_c] or [0]),
        "rss_growth_pct": 100.0 * (rss_end - rss_warm) / rss_warm if rss_warm else float("nan"),
        "latency_s_median_first_third": lat_first, "latency_s_median_last_third": lat_last,
        "latency_s_max": max([s["latency_s"] for s in post_s] or [0]),
        "processing_s_median": median(proc), "processing_s_max": max(proc or [0]),
        # Queue wait of a processed cloud (latency - processing): grows with a backlog.
        "wait_s_median_first_third": median(wait[:third]),
        "wait_s_median_last_third": median(wait[-third:]),
        "processing_s_median_first_third": median(proc[:third]),
        "processing_s_median_last_third": median(proc[-third:]),
        # Slowest cloud callback of the node's life (diagnostics): inference runs on the worker.
        "max_callback_ms": last.get("max_callback_ms", float("nan")),
        "load1_median": median([d["load1"] for d in post]),
        "load1_max": max([d["load1"] for d in post] or [0]),
    }
    # CPU seconds of the node per processed cloud, first vs last third after warm-up: tells a
    # slowdown of the node from contention on the shared machine (wall time up, CPU time flat).
    def cpu_per_cloud(ds):
        ds = [d for d in ds if d.get("node_cpu_s") is not None and d["node_cpu_s"] == d["node_cpu_s"]]
        if len(ds) < 2 or ds[-1]["clouds_processed"] == ds[0]["clouds_processed"]:
            return float("nan")
        return (ds[-1]["node_cpu_s"] - ds[0]["node_cpu_s"]) / (
            ds[-1]["clouds_processed"] - ds[0]["clouds_processed"])
    dthird = max(2, len(post) // 3)
    summary["node_cpu_s_per_cloud_first_third"] = cpu_per_cloud(post[:dthird])
    summary["node_cpu_s_per_cloud_last_third"] = cpu_per_cloud(post[-dthird:])
    summary["latency_ratio_last_first"] = lat_last / lat_first if lat_first else float("nan")
    # Least-squares slope of latency over simulated time after warm-up (s per 10 sim minutes).
    if len(post_s) >= 3:
        ts = [s["sim_s"] for s in post_s]
        ls = [s["latency_s"] for s in post_s]
        mt, ml = statistics.mean(ts), statistics.mean(ls)
        var = sum((t - mt) ** 2 for t in ts)
        slope = sum((t - mt) * (v - ml) for t, v in zip(ts, ls)) / var if var else 0.0
        summary["latency_slope_s_per_10min"] = slope * 600.0
    else:
        summary["latency_slope_s_per_10min"] = float("nan")
    # No backlog: every processed cloud waited at most about one processing time (newest wins).
    summary["backlog_free"] = bool(post_s) and all(
        s["latency_s"] <= 2.0 * summary["processing_s_max"] + 1.0 for s in post_s)
    with open(a.out + ".json", "w") as f:
        json.dump({"summary": summary, "scenes": scenes_c, "diagnostics": diags_c}, f, indent=1)
    with open(a.out + ".csv", "w") as f:
        f.write("sim_s,latency_s,processing_s,instances,input_points\n")
        for s in scenes_c:
            f.write("%.2f,%.3f,%.3f,%d,%d\n" % (s["sim_s"], s["latency_s"], s["processing_s"],
                                                s["instances"], s["input_points"]))
    svg_plot(a.out + ".svg", scenes_c, diags_c, a.sim_minutes, warm,
             "dimr node soak: %.0f simulated min at %.1fx, %d scenes (%s)" % (
                 a.sim_minutes, a.speedup, len(scenes_c), summary["cpu"]))
    print("\nCPU %s, %s" % (summary["cpu"], summary["compute"]))
    print("| metric | value |\n|---|---|")
    for key in ["sim_minutes", "speedup", "wall_minutes", "clouds_sent", "clouds_received",
                "clouds_processed", "queue_drops", "pipeline_errors", "rss_mb_after_warmup",
                "rss_mb_end", "rss_mb_max", "rss_growth_pct", "processing_s_median",
                "processing_s_max", "latency_s_median_first_third",
                "latency_s_median_last_third", "latency_ratio_last_first",
                "latency_slope_s_per_10min", "latency_s_max", "processing_s_median_first_third",
                "processing_s_median_last_third", "wait_s_median_first_third",
                "wait_s_median_last_third", "node_cpu_s_per_cloud_first_third",
                "node_cpu_s_per_cloud_last_third", "max_callback_ms", "load1_median", "load1_max",
                "backlog_free"]:
        v = summary[key]
        print("| %s | %s |" % (key, ("%.3g" % v) if isinstance(v, float) else v))
    print("soak: wrote %s.json, %s.csv, %s.svg" % (a.out, a.out, a.out))
    return 0


if __name__ == "__main__":
    rc = main()
    rospy.signal_shutdown("done")
    sys.exit(rc)
