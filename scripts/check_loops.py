#!/usr/bin/env python3
"""Checks every loop closure / map merge of a run against ground truth (no false loops).

usage: check_loops.py RUN_DIR SEQUENCE_DIR LOG_FILE [SEQUENCE0_DIR RUN0_DIR]
A run in a loaded atlas (rgbd_inertial --load-atlas) also gives the earlier run's sequence and run folder:
its keyframes (the ids in RUN0_DIR/keyframes.txt) are looked up in SEQUENCE0_DIR's ground truth (both
ground truths in one frame, as the simulator's room frame is).
For each "loop closed[ (proximity)]: kfA ~ kfB" / "maps merged|rejoined: ... kfA ~ kfB" line of the run log, compares the
estimated relative pose of the two keyframes (keyframes.txt, final) with the ground-truth one and
prints the error; a loop whose error exceeds 0.10 m or 3 deg is reported FALSE (exit 1).
A loop is also FALSE when its logged correction exceeds 0.10 m plus twice the pair's relative-pose error
in the online poses (trajectory_online.txt, what the map held before the loop): a loop between two places
that only look alike can move the map by metres and still leave a pair the later full BAs put right."""
import re
import sys
from math import *
def qmul(a,b):
    x1,y1,z1,w1=a;x2,y2,z2,w2=b
    return (w1*x2+x1*w2+y1*z2-z1*y2, w1*y2-x1*z2+y1*w2+z1*x2, w1*z2+x1*y2-y1*x2+z1*w2, w1*w2-x1*x2-y1*y2-z1*z2)
def qinv(q): return (-q[0],-q[1],-q[2],q[3])
def rot(q,v):
    p=qmul(qmul(q,(v[0],v[1],v[2],0)),qinv(q)); return p[:3]
def rel(A,B):  # A^-1 B, poses (t,q)
    qi=qinv(A[1]); t=rot(qi,[B[0][i]-A[0][i] for i in range(3)]); return (t,qmul(qi,B[1]))
def load(f,idcol=None):
    out=[]
    for l in open(f):
        if l.startswith('#'): continue
        v=l.split(); out.append(v)
    return out
run,seq,log=sys.argv[1],sys.argv[2],sys.argv[3]
kfs={int(v[8]):(float(v[0]),([float(x) for x in v[1:4]],[float(x) for x in v[4:8]])) for v in load(run+'/keyframes.txt')}
def loadgt(d): return [(float(v[0]),([float(x) for x in v[1:4]],[float(x) for x in v[4:8]])) for v in load(d+'/groundtruth.txt')]
gt=loadgt(seq)
try: online={round(float(v[0]),4):([float(x) for x in v[1:4]],[float(x) for x in v[4:8]]) for v in load(run+'/trajectory_online.txt')}
except OSError: online={}
gt0,loaded=(loadgt(sys.argv[4]),{int(v[8]) for v in load(sys.argv[5]+'/keyframes.txt')}) if len(sys.argv)>5 else ([],set())
def gtat(t,kf=None): return min(gt0 if kf in loaded else gt,key=lambda r:abs(r[0]-t))[1]
bad = 0
for l in open(log):
    m=re.search(r'(loop closed|loop closed \(proximity\)|maps merged|maps rejoined): .*?kf(\d+) ~ kf(\d+)',l)
    if not m: continue
    a,b=int(m.group(2)),int(m.group(3))
    if a not in kfs or b not in kfs: print(m.group(1),a,b,'keyframe culled'); continue
    E=rel(kfs[b][1],kfs[a][1]); G=rel(gtat(kfs[b][0],b),gtat(kfs[a][0],a))
    dt=sqrt(sum((E[0][i]-G[0][i])**2 for i in range(3)))
    dq=qmul(qinv(G[1]),E[1]); ang=degrees(2*acos(min(1,abs(dq[3]))))
    gd=sqrt(sum(x*x for x in G[0]))
    false = dt > 0.10 or ang > 3.0
    note = ""
    c = re.search(r'correction ([0-9.eE+-]+) m', l)
    ta, tb = round(kfs[a][0], 4), round(kfs[b][0], 4)
    if c and ta in online and tb in online:
        O = rel(online[tb], online[ta]); drift = sqrt(sum((O[0][i]-G[0][i])**2 for i in range(3)))
        correction = float(c.group(1)); note = f"; correction {correction:.3f} m, online drift {drift:.3f} m"
        false = false or correction > 0.10 + 2.0 * drift
    bad += false
    print(("FALSE " if false else "") + f"{m.group(1)} kf{a}(t={kfs[a][0]:.1f}) ~ kf{b}(t={kfs[b][0]:.1f}): true distance {gd:.2f} m; relative-pose error {dt*100:.1f} cm {ang:.2f} deg" + note)
sys.exit(1 if bad else 0)
