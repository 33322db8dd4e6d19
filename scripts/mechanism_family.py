#!/usr/bin/env python3
"""Writes mechanism files of scalable families, for N up to a few thousand bodies.

    scripts/mechanism_family.py FAMILY N [-o FILE]      one member (FILE, default stdout)
    scripts/mechanism_family.py all N -o DIR            every family, DIR/<name>.yaml

Families (each kinematically driven: nc == nq, one driver; q0 is an assembled configuration
at t = 0, computed here):

  fourbar_chain N   N four-bar loops in a row. Loop k has ground pivots O_k = (k d, 0) and
                    O_{k+1}; its input link is the previous loop's output link (the crank for
                    k = 0), so consecutive loops share a link. Every loop is a parallelogram
                    (side links c, coupler = ground spacing d), so every side link keeps the
                    crank's angle: an exact truth for tests. The crank swings
                    phi = pi/2 + A sin(omega t), away from the collinear (branch) positions.
                    2N + 1 bodies, nq = 6N + 3.
  scissor_lift N    N pin-jointed X stages. Bars of length l have their origin at the middle,
                    local x along the bar; stage k's bars `l_k` (angle theta) and `r_k`
                    (angle pi - theta) cross at their middles, and their upper ends carry stage
                    k + 1. The bottom end of l_0 is pinned to the ground at the origin, the
                    bottom end of r_0 slides on y = 0 and is driven in x:
                    w(t) = w0 + dw sin(omega t). Closed form: cos(theta) = w / l, top height
                    N l sin(theta). 2N bodies, nq = 6N.
  closed_chain N    One loop of N moving links and the ground: crank (length a), N - 2 coupler
                    links, rocker (length c), N + 1 revolute joints. The loop alone has N - 2
                    degrees of freedom; N - 3 relative_angle joints bend the coupler links into
                    a rigid circular arc whose chord is b, so the mechanism is a Grashof
                    crank-rocker (a, b, c, d) driven through full turns, phi = omega t. Its
                    position equations are one strongly connected block of size ~3N (the loop
                    closes only through all links). N >= 3 links, nq = 3N.

Only the Python standard library is used.
"""

import argparse
import math
import os
import sys

FAMILIES = ("fourbar_chain", "scissor_lift", "closed_chain")


def num(x):
    """A number as the YAML wants it: 17 significant digits, -0 as 0."""
    if x == 0:
        return "0"
    return repr(float(x))


def vec(v):
    return "[" + ", ".join('"%s"' % x if isinstance(x, str) else num(x) for x in v) + "]"


class Writer:
    def __init__(self, name, comment):
        self.lines = ["# " + line if line else "#" for line in comment.strip("\n").split("\n")]
        self.lines.append("name: " + name)

    def params(self, values):
        self.lines.append("parameters:")
        for k, v in values:
            self.lines.append("  %s: %s" % (k, v if isinstance(v, str) else num(v)))

    def section(self, name):
        self.lines.append(name + ":")

    def body(self, name, q0):
        self.lines.append("  - name: %s" % name)
        self.lines.append("    q0: %s" % vec(q0))

    def item(self, **fields):
        first = True
        for k, v in fields.items():
            if isinstance(v, (list, tuple)):
                v = vec(v)
            elif not isinstance(v, str):
                v = num(v)
            elif k in ("f", "value", "length") and not _plain(v):
                v = '"%s"' % v
            self.lines.append(("  - " if first else "    ") + "%s: %s" % (k, v))
            first = False

    def text(self):
        return "\n".join(self.lines) + "\n"


def _plain(v):
    try:
        float(v)
        return True
    except ValueError:
        return False


def revolute(w, i, j, si, sj):
    w.item(type="revolute", i=i, j=j, si=si, sj=sj)


def fourbar_chain(n):
    if n < 1:
        raise ValueError("fourbar_chain needs N >= 1")
    c, d, amp, phi0 = 1.0, 1.5, 0.5, math.pi / 2
    w = Writer("fourbar_chain_%d" % n, """
A chain of %d parallelogram four-bar loops sharing links (scripts/mechanism_family.py).
Loop k: ground pivots O_k = (k d, 0) and O_{k+1}; input link = output link of loop k - 1
(the crank for k = 0); coupler_k from the input tip to the tip of rocker_k (pivot O_{k+1}).
Every side link keeps the crank's angle; couplers stay parallel to the ground.
q0 is the exact configuration at t = 0 (phi = pi/2).""" % n)
    w.params([("c", c), ("d", d), ("amp", amp), ("omega", 1.0)])
    th = phi0  # the crank angle at t = 0
    tip = (c * math.cos(th), c * math.sin(th))
    w.section("bodies")
    w.body("crank", [0, 0, th])
    for k in range(n):
        w.body("coupler_%d" % k, [k * d + tip[0], tip[1], 0])
        w.body("rocker_%d" % k, [(k + 1) * d, 0, th])
    w.section("joints")
    revolute(w, "ground", "crank", [0, 0], [0, 0])
    for k in range(n):
        prev = "crank" if k == 0 else "rocker_%d" % (k - 1)
        revolute(w, prev, "coupler_%d" % k, ["c", 0], [0, 0])
        revolute(w, "coupler_%d" % k, "rocker_%d" % k, ["d", 0], ["c", 0])
        revolute(w, "ground", "rocker_%d" % k, ["%d*d" % (k + 1) if k else "d", 0], [0, 0])
    w.section("drivers")
    w.item(type="absolute_angle", body="crank", f="pi/2 + amp*sin(omega*t)")
    w.section("points")
    w.item(name="top", body="coupler_%d" % (n - 1), s=["d", 0])
    return w.text()


def scissor_lift(n):
    if n < 1:
        raise ValueError("scissor_lift needs N >= 1")
    l, w0, dw = 1.0, 0.6, 0.2
    th = math.acos(w0 / l)
    h = l * math.sin(th)
    w = Writer("scissor_lift_%d" % n, """
An N = %d stage scissor lift (scripts/mechanism_family.py). Bars of length l, origin at the
middle, local x along the bar; l_k rises to the right (angle theta), r_k to the left (angle
pi - theta); they cross at their middles. The bottom of l_0 is pinned at the origin, the
bottom of r_0 slides on y = 0 at x = w(t) = w0 + dw sin(omega t): cos(theta) = w / l, and the
top of the lift is at height N l sin(theta).
q0 is the exact configuration at t = 0 (w = w0).""" % n)
    w.params([("l", l), ("w0", w0), ("dw", dw), ("omega", 1.0)])
    w.section("bodies")
    for k in range(n):
        cx, cy = w0 / 2, (k + 0.5) * h
        w.body("l_%d" % k, [cx, cy, th])
        w.body("r_%d" % k, [cx, cy, math.pi - th])
    w.section("joints")
    lo, hi = ["-l/2", 0], ["l/2", 0]
    revolute(w, "ground", "l_0", [0, 0], lo)
    w.item(type="absolute_y", body="r_0", s=lo, value=0)
    for k in range(n):
        revolute(w, "l_%d" % k, "r_%d" % k, [0, 0], [0, 0])
        if k + 1 < n:
            revolute(w, "r_%d" % k, "l_%d" % (k + 1), hi, lo)
            revolute(w, "l_%d" % k, "r_%d" % (k + 1), hi, lo)
    w.section("drivers")
    w.item(type="absolute_x", body="r_0", s=lo, f="w0 + dw*sin(omega*t)")
    w.section("points")
    w.item(name="top_left", body="r_%d" % (n - 1), s=hi)
    w.item(name="top_right", body="l_%d" % (n - 1), s=hi)
    return w.text()


def closed_chain(n):
    if n < 3:
        raise ValueError("closed_chain needs N >= 3 links")
    a, b, c, d = 1.0, 3.5, 2.5, 3.0  # crank, chord of the coupler arc, rocker, ground
    m = n - 2  # coupler links
    bend = (math.pi / 2) / (m - 1) if m > 1 else 0.0  # total turn of the arc: pi/2
    # Link length so that the arc's chord is b: |sum_k e^{i k bend}| = sin(m bend/2)/sin(bend/2).
    ell = b if m == 1 else b * math.sin(bend / 2) / math.sin(m * bend / 2)
    # The chord's direction in the first link's frame.
    chord_offset = (m - 1) * bend / 2
    # The four-bar at t = 0: crank along +x, A = (a, 0); B above the line A-O4.
    th = 0.0
    ax, ay = a * math.cos(th), a * math.sin(th)
    ox, oy = d, 0.0
    ex, ey = ox - ax, oy - ay
    e = math.hypot(ex, ey)
    alpha = math.acos((b * b + e * e - c * c) / (2 * b * e))  # angle at A between A-O4 and A-B
    chord = math.atan2(ey, ex) + alpha
    bx, by = ax + b * math.cos(chord), ay + b * math.sin(chord)
    w = Writer("closed_chain_%d" % n, """
A closed chain of N = %d links (scripts/mechanism_family.py): crank (length a), %d coupler
links of length l bent by relative_angle joints into a rigid arc (turn pi/2 in all) whose
chord is b, and rocker (length c), pinned to the ground at (0, 0) and (d, 0). A Grashof
crank-rocker (a, b, c, d) driven through full turns; one loop, so the position equations are
one strongly connected block.
q0 is the exact configuration at t = 0 (crank along +x, B above the line A-O4).""" % (n, m))
    w.params([("a", a), ("c", c), ("d", d), ("l", ell), ("bend", bend), ("omega", 1.0)])
    w.section("bodies")
    w.body("crank", [0, 0, th])
    phi = chord - chord_offset
    px, py = ax, ay
    for k in range(m):
        w.body("link_%d" % k, [px, py, phi])
        px, py = px + ell * math.cos(phi), py + ell * math.sin(phi)
        phi += bend
    w.body("rocker", [ox, oy, math.atan2(by - oy, bx - ox)])
    w.section("joints")
    revolute(w, "ground", "crank", [0, 0], [0, 0])
    revolute(w, "crank", "link_0", ["a", 0], [0, 0])
    for k in range(1, m):
        revolute(w, "link_%d" % (k - 1), "link_%d" % k, ["l", 0], [0, 0])
        w.item(type="relative_angle", i="link_%d" % (k - 1), j="link_%d" % k, value="bend")
    revolute(w, "link_%d" % (m - 1), "rocker", ["l", 0], ["c", 0])
    revolute(w, "ground", "rocker", ["d", 0], [0, 0])
    w.section("drivers")
    w.item(type="absolute_angle", body="crank", f="omega*t")
    w.section("points")
    w.item(name="B", body="rocker", s=["c", 0])
    return w.text()


def generate(family, n):
    return {"fourbar_chain": fourbar_chain, "scissor_lift": scissor_lift,
            "closed_chain": closed_chain}[family](n)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("family", choices=FAMILIES + ("all",))
    ap.add_argument("n", type=int, help="family size N")
    ap.add_argument("-o", "--output", help="file (one family) or directory (all)")
    args = ap.parse_args(argv)
    try:
        if args.family == "all":
            if not args.output:
                ap.error("'all' needs -o DIR")
            os.makedirs(args.output, exist_ok=True)
            for f in FAMILIES:
                text = generate(f, args.n)
                with open(os.path.join(args.output, "%s_%d.yaml" % (f, args.n)), "w") as out:
                    out.write(text)
            return 0
        text = generate(args.family, args.n)
    except ValueError as err:
        print("error: %s" % err, file=sys.stderr)
        return 2
    if args.output:
        with open(args.output, "w") as out:
            out.write(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
