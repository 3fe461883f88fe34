#!/usr/bin/env python3
"""Checks the IMU initialisation and its refinements of a run against ground truth (evaluation only).

usage: check_imu_init.py SEQUENCE_DIR LOG_FILE
For each "IMU initialised/refined over N keyframes (S s): g_w = (...) ... b_g = (...) ... b_a = (...)"
line of the run log, prints the angle between the estimated gravity and the true gravity in the
map frame, and the gyroscope / accelerometer bias errors against imu_biases.txt at the time of the
estimate. The map frame is the body frame of the first frame (tracking starts at the identity), so
the true gravity there is R_w_b0^T (0, 0, -9.81) with T_w_b0 = T_w_c0 T_b_c^-1 (groundtruth.txt,
calib.yaml's IMU.T_b_c1). The time of an estimate is the first frame time plus the logged span
after the first keyframe (good for the first map)."""
import re
import sys
from math import acos, degrees, sqrt


def qmul(a, b):
    x1, y1, z1, w1 = a
    x2, y2, z2, w2 = b
    return (w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2)


def qinv(q):
    return (-q[0], -q[1], -q[2], q[3])


def rot(q, v):
    return qmul(qmul(q, (v[0], v[1], v[2], 0.0)), qinv(q))[:3]


def mat_to_quat(m):  # rows of a 3x3 rotation
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        s = sqrt(tr + 1.0) * 2
        return ((m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, 0.25 * s)
    i = max(range(3), key=lambda k: m[k][k])
    j, k = (i + 1) % 3, (i + 2) % 3
    s = sqrt(1.0 + m[i][i] - m[j][j] - m[k][k]) * 2
    q = [0.0, 0.0, 0.0, (m[k][j] - m[j][k]) / s]
    q[i] = 0.25 * s
    q[j] = (m[j][i] + m[i][j]) / s
    q[k] = (m[k][i] + m[i][k]) / s
    return tuple(q)


def vec(text):
    return [float(x) for x in text.replace(',', ' ').split()]


def angle_deg(a, b):
    na, nb = sqrt(sum(x * x for x in a)), sqrt(sum(x * x for x in b))
    return degrees(acos(max(-1.0, min(1.0, sum(x * y for x, y in zip(a, b)) / (na * nb)))))


def main():
    seq, log = sys.argv[1], sys.argv[2]
    calib = open(seq + '/calib.yaml').read()
    data = vec(re.search(r'IMU\.T_b_c1:.*?data:\s*\[([^\]]*)\]', calib, re.S).group(1))
    q_b_c = mat_to_quat([data[0:3], data[4:7], data[8:11]])
    gt = [[float(x) for x in l.split()] for l in open(seq + '/groundtruth.txt') if not l.startswith('#')]
    t0 = gt[0][0]
    q_w_c0 = tuple(gt[0][4:8])
    q_w_b0 = qmul(q_w_c0, qinv(q_b_c))
    g_true = rot(qinv(q_w_b0), (0.0, 0.0, -9.81))
    biases = [[float(x) for x in l.split()] for l in open(seq + '/imu_biases.txt') if not l.startswith('#')]

    def bias_at(t):
        return min(biases, key=lambda r: abs(r[0] - t))

    pattern = re.compile(r'IMU (initialised|refined)(?: \([^)]*\))? over (\d+) keyframes \(([\d.e+-]+) s\): g_w = \(([^)]*)\).*?'
                         r'b_g = \(([^)]*)\).*?b_a = \(([^)]*)\)')
    found = 0
    first_span = None
    for line in open(log):
        m = pattern.search(line)
        if not m:
            continue
        found += 1
        span = float(m.group(3))
        first_span = span if first_span is None else first_span
        g, b_g, b_a = vec(m.group(4)), vec(m.group(5)), vec(m.group(6))
        truth = bias_at(t0 + span)
        e_g = sqrt(sum((b_g[i] - truth[1 + i]) ** 2 for i in range(3)))
        e_a = sqrt(sum((b_a[i] - truth[4 + i]) ** 2 for i in range(3)))
        n_a = sqrt(sum(truth[4 + i] ** 2 for i in range(3)))
        print(f"{m.group(1):11s} over {m.group(2):>3s} keyframes ({span:5.1f} s): gravity error "
              f"{angle_deg(g, g_true):.3f} deg, |b_g err| {e_g:.5f} rad/s, |b_a err| {e_a:.4f} m/s^2 "
              f"(true |b_a| {n_a:.4f})")
    if not found:
        print("no IMU initialisation in the log")
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
