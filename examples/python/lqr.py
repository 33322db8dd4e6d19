#!/usr/bin/env python3
"""An inverted pendulum on a cart stabilized by LQR on kinegen's exact linear model.

examples/dynamics/cart_pole.yaml: a cart on a rail, a pole pinned to it, the horizontal force
on the cart a run-time input (push_x). `Mechanism.linearize()` gives the exact A and B of
x' = f(x, u), x = (x, phi, x.v, phi.v), at the upright rest position (value0); scipy's
solve_continuous_are gives the gain K of u = -K (x - x_up). The closed loop then runs on
kinegen's own nonlinear dynamics (Mechanism.dynamics, the right-hand side that linearize
differentiates) under scipy's solve_ivp, from the pole tilted by 0.25 rad and the cart at
rest; the pole comes upright and the cart back to the origin. Draws x, the pole's tilt and the
force over time (matplotlib), to lqr.png by default.

Run from the repository root after building:
    PYTHONPATH=build/python python3 examples/python/lqr.py [-o lqr.png]
"""
import argparse
import pathlib

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import solve_continuous_are

import kinegen

HERE = pathlib.Path(__file__).resolve().parent
MECH = str(HERE.parent / "dynamics" / "cart_pole.yaml")
Q = np.diag([10.0, 100.0, 1.0, 1.0])  # weights on x, phi, x.v, phi.v
R = np.array([[0.1]])                  # on the force


def design(mech):
    """The linear model at the upright rest position and the LQR gain on it."""
    lin = mech.linearize()
    a, b = lin["A"], lin["B"]
    p = solve_continuous_are(a, b, Q, R)
    k = np.linalg.solve(R, b.T @ p)
    return lin, k


def closed_loop(mech, lin, k, tilt=0.25, t1=6.0):
    """The nonlinear closed loop from the pole tilted by `tilt`, sampled every 10 ms."""
    nf = len(mech.free)
    x_up = lin["x"]

    def force(x):
        return -k @ (x - x_up)

    def f(t, x):
        zdd = mech.dynamics(t, x[:nf], x[nf:], force(x))
        return np.concatenate([x[nf:], zdd])

    x0 = x_up.copy()
    x0[1] += tilt
    t = np.linspace(0.0, t1, 601)
    run = solve_ivp(f, (0.0, t1), x0, t_eval=t, rtol=1e-9, atol=1e-11)
    if not run.success:
        raise RuntimeError(run.message)
    u = np.array([force(x)[0] for x in run.y.T])
    return run.t, run.y, u


def plot(t, y, u, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    top.plot(t, y[0], label="cart x [m]")
    top.plot(t, y[1] - np.pi / 2, label="pole tilt phi - pi/2 [rad]")
    top.axhline(0, color="0.7", lw=0.8)
    top.legend()
    top.set_title("cart-pole under LQR on kinegen's exact A, B")
    bottom.plot(t, u, color="C2")
    bottom.set_ylabel("push_x [N]")
    bottom.set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="lqr.png", help="the plot (PNG)")
    args = parser.parse_args()
    mech = kinegen.Mechanism(MECH)
    lin, k = design(mech)
    open_loop = np.linalg.eigvals(lin["A"])
    closed = np.linalg.eigvals(lin["A"] - lin["B"] @ k)
    print("states", lin["states"], "inputs", lin["inputs"])
    print("open loop: largest Re(eigenvalue) %.4f (unstable)" % open_loop.real.max())
    print("closed loop: largest Re(eigenvalue) %.4f" % closed.real.max())
    print("K =", np.array2string(k, precision=4))
    t, y, u = closed_loop(mech, lin, k)
    tilt, cart = abs(y[1, -1] - np.pi / 2), abs(y[0, -1])
    print("at t = %g s: tilt %.2e rad, cart %.2e m, peak force %.3g N"
          % (t[-1], tilt, cart, abs(u).max()))
    plot(t, y, u, args.output)
    print("wrote", args.output)
    return 0 if tilt < 1e-3 and cart < 1e-2 else 1


if __name__ == "__main__":
    raise SystemExit(main())
