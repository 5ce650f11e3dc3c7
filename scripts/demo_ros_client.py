#!/usr/bin/env python3
"""scripts/demo.sh's ROS client: waits until the dimr node has reconstructed the bag's last
/map_cloud, calls ~save_scene into OUT_DIR and prints a summary (instances per class, latency,
and - with the room's SynthScan ground truth GT_JSON - the GT CAD objects found: same class,
box centre within 0.35 m in xy, as in the real-model rostest).

usage: demo_ros_client.py BAG OUT_DIR [TIMEOUT_S [GT_JSON]]
Exit status 0 when a scene with at least one instance was saved, 1 otherwise."""
import collections
import json
import math
import os
import sys
import threading
import time

import rosbag
import rospy
from dimr.msg import SceneMeshes
from dimr.srv import SaveScene


def compare_with_gt(scene, gt_path):
    """(GT CAD objects per class, GT objects found, predictions that are a GT object)."""
    with open(gt_path) as f:
        gt = [g for g in json.load(f)["instances"] if g["cad_class"] >= 0]
    used, found = set(), 0
    for g in gt:
        best, who = 0.35, -1
        for i, p in enumerate(scene.instances):
            if i in used or p.class_id != g["cad_class"]:
                continue
            d = math.hypot(p.pose.position.x - g["box"]["center"][0],
                           p.pose.position.y - g["box"]["center"][1])
            if d < best:
                best, who = d, i
        if who >= 0:
            used.add(who)
            found += 1
    return collections.Counter(g["category"] for g in gt), found, len(used)


def main():
    if len(sys.argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    bag_path, out_dir = sys.argv[1], os.path.abspath(sys.argv[2])
    timeout = float(sys.argv[3]) if len(sys.argv) > 3 else 900.0
    gt_path = sys.argv[4] if len(sys.argv) > 4 else ""
    stamps = []
    with rosbag.Bag(bag_path) as bag:
        for _, msg, _ in bag.read_messages(topics=["/map_cloud"]):
            stamps.append((msg.header.stamp, msg.width * msg.height))
    if not stamps:
        print("demo: %s has no /map_cloud messages" % bag_path, file=sys.stderr)
        return 1
    last_stamp, last_points = stamps[-1]
    rospy.init_node("dimr_demo_client", anonymous=True, disable_signals=True)
    scenes = []
    got = threading.Event()

    def on_scene(m):
        scenes.append(m)
        print("demo: scene of cloud @ %.1f s: %d instances, %d input points, processing %.1f s,"
              " latency %.1f s" % (m.header.stamp.to_sec(), len(m.instances), m.input_points,
                                   m.processing_time, m.latency), flush=True)
        if m.header.stamp == last_stamp:
            got.set()

    rospy.Subscriber("/scene_meshes", SceneMeshes, on_scene, queue_size=10)
    print("demo: %d map clouds in the bag, waiting for the scene of the last one (%d points)"
          % (len(stamps), last_points), flush=True)
    # Wall-clock waits only: with use_sim_time the clock stops when the bag ends.
    if not got.wait(timeout):
        print("demo: no scene for the last map cloud within %.0f s" % timeout, file=sys.stderr)
        return 1
    scene = [s for s in scenes if s.header.stamp == last_stamp][-1]
    rospy.wait_for_service("/dimr/save_scene", timeout=30)
    res = rospy.ServiceProxy("/dimr/save_scene", SaveScene)(out_dir, "ply")
    if not res.success:
        print("demo: save_scene failed: %s" % res.message, file=sys.stderr)
        return 1
    per_class = collections.Counter(i.class_name for i in scene.instances)
    processed = [s for s in scenes if s.instances or s.input_points]
    summary = {
        "bag": bag_path,
        "map_clouds": len(stamps),
        "scenes_received": len(processed),
        "input_points": scene.input_points,
        "instances": len(scene.instances),
        "instances_per_class": dict(sorted(per_class.items())),
        "processing_s": round(scene.processing_time, 3),
        "latency_s": round(scene.latency, 3),
        "files": len(res.files),
    }
    if gt_path:
        gt_classes, found, true_pred = compare_with_gt(scene, gt_path)
        summary["gt_cad_objects"] = dict(sorted(gt_classes.items()))
        summary["gt_found"] = found
        summary["predictions_matching_gt"] = true_pred
    with open(os.path.join(out_dir, "summary.json"), "w") as f:
        json.dump(summary, f, indent=2)
    print("demo: saved %d files into %s" % (len(res.files), out_dir))
    print("demo: %d instances: %s" % (len(scene.instances), ", ".join(
        "%s %d" % kv for kv in sorted(per_class.items()))))
    print("demo: last map cloud %d points -> %d after the input voxel filter; processing %.2f s,"
          " latency (cloud received -> scene built) %.2f s" % (
              last_points, scene.input_points, scene.processing_time, scene.latency))
    if gt_path:
        print("demo: ground truth: %d CAD objects (%s); %d found, %d of %d predictions are one of"
              " them (same class, centre within 0.35 m)" % (
                  sum(gt_classes.values()),
                  ", ".join("%s %d" % kv for kv in sorted(gt_classes.items())), found, true_pred,
                  len(scene.instances)))
    time.sleep(0.1)
    return 0 if scene.instances else 1


if __name__ == "__main__":
    rc = main()
    rospy.signal_shutdown("done")
    sys.exit(rc)
