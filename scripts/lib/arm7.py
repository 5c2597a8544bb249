#!/usr/bin/env python3
"""A seven-joint arm for the benchmarks (scripts/bench, scripts/bench-instructions): an anthropomorphic arm
written here, shoulder, elbow and wrist axes as a Panda's or an iiwa's, masses on every link, joint
stiffnesses of that size. Writes FOLDER/arm7.urdf, FOLDER/arm7.toml and FOLDER/joints7.csv (COUNT seeded
random configurations).
Usage: scripts/lib/arm7.py FOLDER COUNT"""
import random, sys
tmp, count = sys.argv[1], int(sys.argv[2])
# (origin xyz, rpy, axis, mass, centre) per joint: alternating axes, links of 0.34, 0.4, 0.4, 0.126 m.
joints = [("0 0 0.34", "0 0 0", "0 0 1", 4.0, "0 0 -0.05"), ("0 0 0", "-1.5708 0 0", "0 0 1", 4.0, "0 -0.05 0"),
          ("0 -0.4 0", "1.5708 0 0", "0 0 1", 3.0, "0 0 -0.05"), ("0 0 0", "1.5708 0 0", "0 0 1", 2.7, "0 0.05 0"),
          ("0 0.4 0", "-1.5708 0 0", "0 0 1", 1.7, "0 0 -0.05"), ("0 0 0", "1.5708 0 0", "0 0 1", 1.8, "0 0.02 0"),
          ("0 0 0", "-1.5708 0 0", "0 0 1", 0.3, "0 0 0.02")]
links = ["<link name='l0'/>"]
body = []
for i, (xyz, rpy, axis, kg, c) in enumerate(joints, 1):
    links.append(f"<link name='l{i}'><inertial><origin xyz='{c}'/><mass value='{kg}'/>"
                 "<inertia ixx='0.01' ixy='0' ixz='0' iyy='0.01' iyz='0' izz='0.01'/></inertial></link>")
    body.append(f"<joint name='J{i}' type='revolute'><parent link='l{i-1}'/><child link='l{i}'/>"
                f"<origin xyz='{xyz}' rpy='{rpy}'/><axis xyz='{axis}'/></joint>")
links.append("<link name='tool'/>")
body.append("<joint name='T' type='fixed'><parent link='l7'/><child link='tool'/><origin xyz='0 0 0.126'/></joint>")
open(f"{tmp}/arm7.urdf", "w").write("<robot name='arm7'>" + "".join(links + body) + "</robot>")
k = [4e8, 4e8, 3e8, 3e8, 8e7, 8e7, 5e7]
springs = ", ".join(f"J{i} = {{ stiffness = {v} }}" for i, v in enumerate(k, 1))
open(f"{tmp}/arm7.toml", "w").write(f'name = "arm7"\ngravity = [0, 0, -9.81]\n[[leg]]\nname = "arm"\n[leg.urdf]\n'
                                    f'file = "arm7.urdf"\nroot = "l0"\ntip = "tool"\njoints = {{ {springs} }}\n')
r = random.Random(47)
with open(f"{tmp}/joints7.csv", "w") as f:
    f.write(",".join(f"q_J{i}" for i in range(1, 8)) + "\n")
    for _ in range(count):
        f.write(",".join(f"{r.uniform(-2.5, 2.5):.6f}" for _ in range(7)) + "\n")
