#!/usr/bin/env python3
"""Writes the N-four-bar mechanism after the IFToMM multibody benchmark A02 (the library of
computational benchmark problems of the IFToMM Technical Committee for Multibody Dynamics,
problem A02; Gonzalez, Dopico, Lugris and Cuadrado, "A benchmarking system for MBS simulation
software", Multibody System Dynamics 16 (2006) 179-190).

    examples/dynamics/n_four_bar.py N [-o FILE]          one file (default stdout)

N + 1 cranks of length l on ground pins at x = 0, l, ..., N l and N couplers of length l
joining the cranks' tips B_0 ... B_N: N parallelogram windows sharing their sides, 2N + 1
uniform rods of mass m (inertia m l^2 / 12 about the centre), gravity g down. One degree of
freedom, the angle theta of crank 0, starting at 45 degrees with B_0's x-velocity 1 m/s
(theta' = -1 / (l sin 45) = -sqrt(2) rad/s), so the mechanism falls to the right through the
flat position theta = 0, swings under the ground line and back through theta = pi: at both flat
positions the cranks and couplers are collinear, Phi_q loses N ranks (N + 1 degrees of freedom
for an instant) and the minimal-coordinates method cannot pass. On the parallelogram branch
every crank keeps theta and every coupler stays horizontal, so the motion is the one of a
single degree of freedom with the energy
    E = 1/2 I theta'^2 + G sin(theta),  I = (N + 1) m l^2 / 3 + N m l^2,  G = g m l (3N + 1) / 2
(theta'' = -G cos(theta) / I): tests/test_augmented.cpp checks B_0 against it.

Only the Python standard library is used.
"""

import argparse
import math
import sys


def num(x):
    return "0" if x == 0 else repr(float(x))


def n_four_bar(n):
    if n < 1:
        raise ValueError("the N-four-bar needs N >= 1")
    th = math.pi / 4
    tip = (math.cos(th), math.sin(th))
    out = [
        "# The N-four-bar after the IFToMM multibody benchmark A02, N = %d (written by" % n,
        "# examples/dynamics/n_four_bar.py, which describes it): %d cranks on ground pins at" % (n + 1),
        "# x = 0..%d, %d couplers, uniform rods, starting at 45 degrees with B0's x-velocity 1 m/s." % (n, n),
        "# Both flat positions (theta = 0, pi) are singular: use kinegen simulate --method augmented.",
        "name: n_four_bar_%d" % n,
        "parameters:",
        "  m: 1.0",
        "  l: 1.0",
        "  g: 9.81",
        "gravity: [0, -g]",
        "bodies:",
    ]
    rod = ['    mass: m', '    inertia: "m*l^2/12"', '    com: ["l/2", 0]']
    for k in range(n + 1):
        out += ["  - name: crank_%d" % k, "    q0: [%s, 0, %s]" % (num(k), num(th))] + rod
    for k in range(n):
        out += ["  - name: coupler_%d" % k,
                "    q0: [%s, %s, 0]" % (num(k + tip[0]), num(tip[1]))] + rod
    out.append("joints:")
    for k in range(n + 1):
        x = "0" if k == 0 else ("l" if k == 1 else '"%d*l"' % k)
        out.append("  - {type: revolute, name: O%d, i: ground, j: crank_%d, si: [%s, 0]}" % (k, k, x))
    for k in range(n):
        out.append("  - {type: revolute, name: B%d_left, i: crank_%d, j: coupler_%d, si: [l, 0]}"
                   % (k, k, k))
        out.append("  - {type: revolute, name: B%d_right, i: coupler_%d, j: crank_%d, si: [l, 0],"
                   " sj: [l, 0]}" % (k + 1, k, k + 1))
    out += [
        "free:",
        "  - type: absolute_angle",
        "    name: theta",
        "    body: crank_0",
        '    value0: "pi/4"',
        '    v0: "-1/(l*sin(pi/4))"',
        "points:",
        "  - {name: B0, body: crank_0, s: [l, 0]}",
        "  - {name: B%d, body: crank_%d, s: [l, 0]}" % (n, n),
    ]
    return "\n".join(out) + "\n"


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("n", type=int)
    p.add_argument("-o", "--output")
    a = p.parse_args()
    text = n_four_bar(a.n)
    if a.output:
        with open(a.output, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
