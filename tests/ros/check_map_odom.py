#!/usr/bin/env python3
"""Checks the ROS node's map -> odom against its poses (tests/ros/node_test.sh).

Usage: check_map_odom.py POSES.txt MAP_ODOM.txt ODOM_CAMERA MIN_MATCHED

POSES.txt: the node's poses (map -> camera), MAP_ODOM.txt: its map -> odom transforms, both TUM
lines as ros_test_tool writes them (stamp x y z qx qy qz qw); ODOM_CAMERA: the constant odom ->
camera the player broadcast ("x,y,z,qx,qy,qz,qw"). For every map -> odom at a pose's stamp,
map -> odom * odom -> camera must be that pose within 1 mm and 1 mrad, and at least MIN_MATCHED
of them must be found. The quaternion algebra is written out here, independent of the node's.
"""
import math
import sys


def mul(a, b):
    (x1, y1, z1, w1), (x2, y2, z2, w2) = a, b
    return (w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2)


def rotate(q, v):
    return mul(mul(q, (v[0], v[1], v[2], 0.0)), (-q[0], -q[1], -q[2], q[3]))[:3]


def read(path):
    rows = {}
    for line in open(path):
        f = line.split()
        if f:
            rows[f[0]] = ([float(x) for x in f[1:4]], tuple(float(x) for x in f[4:8]))
    return rows


def main():
    poses, map_odom = read(sys.argv[1]), read(sys.argv[2])
    odom_camera = [float(x) for x in sys.argv[3].split(",")]
    t_oc, q_oc = odom_camera[:3], tuple(odom_camera[3:])
    worst_t = worst_r = 0.0
    matched = 0
    for stamp, (t, q) in map_odom.items():
        if stamp not in poses:
            continue
        matched += 1
        composed_t = [a + b for a, b in zip(t, rotate(q, t_oc))]
        composed_q = mul(q, q_oc)
        pose_t, pose_q = poses[stamp]
        worst_t = max(worst_t, math.dist(composed_t, pose_t))
        # The angle of the rotation between them (atan2: acos loses precision near 1).
        x, y, z, w = mul((-pose_q[0], -pose_q[1], -pose_q[2], pose_q[3]), composed_q)
        worst_r = max(worst_r, 2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w)))
    print(f"map->odom: {len(map_odom)} transforms, {matched} at a pose's stamp; "
          f"map->odom * odom->camera against the pose: at most {worst_t * 1000:.4f} mm, "
          f"{worst_r * 1000:.4f} mrad")
    ok = matched >= int(sys.argv[4]) and worst_t <= 0.001 and worst_r <= 0.001
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
