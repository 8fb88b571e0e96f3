#!/usr/bin/env python3
"""Writes the line-symmetric Bricard linkage descriptions of this folder (Python 3, standard
library only; the loop writer is bennett.py's).

A line-symmetric Bricard six-bar repeats its DH links: (a, α, d) of links 4, 5 and 6 are those
of links 1, 2 and 3, and so are its joint angles, θ4 = θ1, θ5 = θ2, θ6 = θ3. The loop closes
when (L1 L2 L3)² = I with Lk = Rz(θk) Tz(dk) Tx(ak) Rx(αk): L1 L2 L3 is then the half-turn about
the symmetry line. For a given θ1 these are 12 equations of rank 2 in θ2 and θ3, solved here by
Gauss-Newton and traced from θ1 = 0 in steps of 1° (the same construction as
`tests/src/redundancy.rs`'s reference, written twice).

The geometry (a = 1, 1.2, 0.8; α = 60°, 100°, 40°; d = 0.2, −0.3, 0.1) was chosen so that θ1
turns fully: on the branch through (θ2, θ3) ≈ (191.8°, 2.1°) at θ1 = 0, θ2 swings between
about 168° and 215° and θ3 makes one full turn backwards per turn of θ1, and the 6 × 6 matrix
of the joint screws keeps its fifth singular value above 0.086 of its first over the cycle
(rank 5: mobility 1, no bifurcation). Grübler counts 5·6 − 6·5 = 0; one row is redundant.

Run from the repository root: python3 tests/redundancy/bricard.py
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bennett import DEG, STARTS, STEPS, dh, mul, write_loop  # noqa: E402

LINKS = [(1.0, 60 * DEG, 0.2), (1.2, 100 * DEG, -0.3), (0.8, 40 * DEG, 0.1)]
# The branch at θ1 = 0, to about 1e-3 rad: Gauss-Newton refines it.
ANCHOR = (191.8 * DEG, 2.1 * DEG)


def residual(theta1, x):
    m = mul(mul(dh(theta1, *LINKS[0]), dh(x[0], *LINKS[1])), dh(x[1], *LINKS[2]))
    m2 = mul(m, m)
    return [m2[i][j] - (1 if i == j else 0) for i in range(3) for j in range(4)]


def solve(theta1, x):
    """Gauss-Newton from x on (L1 L2 L3)² = I, Jacobian by central differences."""
    for _ in range(50):
        r = residual(theta1, x)
        h = 1e-6
        cols = []
        for k in range(2):
            up, down = list(x), list(x)
            up[k] += h
            down[k] -= h
            cols.append([(u - d) / (2 * h) for u, d in zip(residual(theta1, up), residual(theta1, down))])
        a11 = sum(v * v for v in cols[0])
        a12 = sum(u * v for u, v in zip(cols[0], cols[1]))
        a22 = sum(v * v for v in cols[1])
        b1 = sum(u * v for u, v in zip(cols[0], r))
        b2 = sum(u * v for u, v in zip(cols[1], r))
        det = a11 * a22 - a12 * a12
        dx = [-(a22 * b1 - a12 * b2) / det, -(a11 * b2 - a12 * b1) / det]
        x = [x[0] + dx[0], x[1] + dx[1]]
        if max(abs(v) for v in dx) < 1e-15:
            break
    assert max(abs(v) for v in residual(theta1, x)) < 1e-13, (theta1, x)
    return x


def branch(theta1):
    """(θ2, θ3) on the branch at θ1 ≥ 0, traced from the anchor in steps of at most 1°."""
    x = solve(0.0, list(ANCHOR))
    n = max(1, math.ceil(theta1 / DEG))
    for k in range(1, n + 1):
        x = solve(theta1 * k / n, x)
    return x


if __name__ == "__main__":
    for start in STARTS:
        theta1 = start * DEG
        theta2, theta3 = branch(theta1)
        for step in STEPS:
            name = f"bricard_{start}_{step}"
            comment = [
                "Written by tests/redundancy/bricard.py (see its docstring): a line-symmetric Bricard",
                "linkage of six revolutes, DH links (a, α, d) = (1, 60°, 0.2), (1.2, 100°, −0.3),",
                "(0.8, 40°, 0.1), repeated for links 4 to 6; joint k's angle is the DH angle θk, and",
                "θ4 = θ1, θ5 = θ2, θ6 = θ3 with (L1 L2 L3)² = I. J1 is driven at 1 rad/s from",
                f"θ1 = {start}° through a full turn in steps of {step}°. Grübler counts 5·6 − 6·5 = 0",
                "degrees of freedom; the mobility is 1 and 1 row is redundant.",
            ]
            links = LINKS + LINKS
            thetas = [theta1, theta2, theta3, theta1, theta2, theta3]
            write_loop(
                name,
                f"Line-symmetric Bricard linkage from theta1 = {start} deg",
                comment, links, thetas, step * DEG, 360 // step,
            )
