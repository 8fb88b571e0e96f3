#!/usr/bin/env python3
"""Writes the Bennett linkage descriptions of this folder (Python 3, standard library only).

The loop is built from Denavit-Hartenberg links T(θ, a, α) = Rz(θ) Tx(a) Rx(α): the ground
frame is joint J1's, link k's frame is joint k's after its rotation θk, and the joint points,
axes and reference vectors are the DH frames' origins, z and x axes, so that every joint's
angle (from ref_i to ref_j about axis_i) is its DH angle θk. A Bennett linkage has
a1 = a3 = a, a2 = a4 = b, α1 = α3, α2 = α4 and a / sin α1 = b / sin α2; then
tan(θ1/2) tan(θ2/2) = sin((α2 + α1)/2) / sin((α2 − α1)/2), θ3 = −θ1 and θ4 = −θ2, which
closes the loop exactly (checked below before anything is written). The initial estimates
are the assembled configuration at the start angle, from that closed form.

Run from the repository root: python3 tests/redundancy/bennett.py
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def rz(t):
    c, s = math.cos(t), math.sin(t)
    return [[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]


def rx(t):
    c, s = math.cos(t), math.sin(t)
    return [[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]]


def tx(a):
    return [[1, 0, 0, a], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]


def link(theta, a, alpha):
    return mul(mul(rz(theta), tx(a)), rx(alpha))


def euler(m):
    """Euler parameters (e0 ≥ 0 branch, Shepperd's method) of the rotation part of m."""
    tr = m[0][0] + m[1][1] + m[2][2]
    cands = [tr, m[0][0], m[1][1], m[2][2]]
    k = max(range(4), key=lambda i: cands[i])
    if k == 0:
        e0 = math.sqrt(1 + tr) / 2
        e = [(m[2][1] - m[1][2]) / (4 * e0), (m[0][2] - m[2][0]) / (4 * e0), (m[1][0] - m[0][1]) / (4 * e0)]
        p = [e0] + e
    else:
        i = k - 1
        j, l = (i + 1) % 3, (i + 2) % 3
        ei = math.sqrt(1 + 2 * m[i][i] - tr) / 2
        e0 = (m[l][j] - m[j][l]) / (4 * ei)
        e = [0.0, 0.0, 0.0]
        e[i] = ei
        e[j] = (m[j][i] + m[i][j]) / (4 * ei)
        e[l] = (m[l][i] + m[i][l]) / (4 * ei)
        p = [e0] + e
    if p[0] < 0:
        p = [-x for x in p]
    return p


def closed_form(theta1, alpha1, alpha2):
    k = math.sin((alpha2 + alpha1) / 2) / math.sin((alpha2 - alpha1) / 2)
    return 2 * math.atan2(k * math.cos(theta1 / 2), math.sin(theta1 / 2))


def fmt(v):
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def identity():
    return [[1 if i == j else 0 for j in range(4)] for i in range(4)]


def inverse(m):
    """The inverse of a rigid motion (rotation part transposed)."""
    r = [[m[j][i] for j in range(3)] for i in range(3)]
    p = [-sum(r[i][k] * m[k][3] for k in range(3)) for i in range(3)]
    return [r[0] + [p[0]], r[1] + [p[1]], r[2] + [p[2]], [0, 0, 0, 1]]


def tz(d):
    return [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, d], [0, 0, 0, 1]]


def dh(theta, a, alpha, d=0.0):
    """The DH link Rz(θ) Tz(d) Tx(a) Rx(α)."""
    return mul(mul(mul(rz(theta), tz(d)), tx(a)), rx(alpha))


def write_loop(name, title, comment, links, thetas, step, steps):
    """Writes a closed loop of revolutes J1 … Jn, ground and link1 … link(n−1), from its DH links
    (a, α, d) and joint angles θ (the initial configuration), J1 driven at 1 rad/s from θ1
    over `steps` grid steps of `step` s. Checks the loop's closure first. Joint k's angle (from
    ref_i to ref_j about axis_i) is its DH angle θk: link k's frame is Fk−1 Rz(θk), and joint
    k + 1 sits at (ak, 0, dk) on it with axis Rx(αk) z and reference x."""
    n = len(links)
    loop = identity()
    for (a, alpha, d), theta in zip(links, thetas):
        loop = mul(loop, dh(theta, a, alpha, d))
    closure = max(abs(loop[i][j] - (1 if i == j else 0)) for i in range(4) for j in range(4))
    assert closure < 1e-13, (name, closure)
    bodies = []
    g = identity()
    for k in range(n - 1):
        g = mul(g, rz(thetas[k]))
        bodies.append(([g[i][3] for i in range(3)], euler(g)))
        a, alpha, d = links[k]
        g = mul(g, mul(mul(tz(d), tx(a)), rx(alpha)))
    out = []
    w = out.append
    w(f"# {title}")
    for line in comment:
        w(f"# {line}" if line else "#")
    w("")
    w(f'name = "{name}"')
    w(f'description = "{title}"')
    w("")
    w("[time]")
    w("start = 0.0")
    w(f"end = {step * steps!r}")
    w(f"steps = {steps}")
    w("")
    w("[[bodies]]")
    w('name = "ground"')
    w("ground = true")
    for k, (r, p) in enumerate(bodies):
        w("")
        w("[[bodies]]")
        w(f'name = "link{k + 1}"')
        w(f"r = {fmt(r)}")
        w(f"p = {fmt(p)}")
    z = [0.0, 0.0, 1.0]
    x = [1.0, 0.0, 0.0]
    o = [0.0, 0.0, 0.0]

    def column(m, j):
        # + 0.0 writes −0.0 as 0.0.
        return [float(m[i][j]) + 0.0 for i in range(3)]

    def on_link(a, alpha, d):
        return [a, 0.0, d], [0.0, -math.sin(alpha), math.cos(alpha)]

    # The last joint's frame after its rotation, seen from the ground (J1's frame):
    # (Tz(dn) Tx(an) Rx(αn))⁻¹.
    last = inverse(mul(mul(tz(links[-1][2]), tx(links[-1][0])), rx(links[-1][1])))
    joints = [("J1", "ground", "link1", o, z, o, z, x)]
    for k in range(1, n):
        body_j = f"link{k + 1}" if k < n - 1 else "ground"
        point_i, axis_i = on_link(*links[k - 1])
        if k < n - 1:
            point_j, axis_j, ref_j = o, z, x
        else:
            point_j, axis_j, ref_j = column(last, 3), column(last, 2), column(last, 0)
        joints.append((f"J{k + 1}", f"link{k}", body_j, point_i, axis_i, point_j, axis_j, ref_j))
    for name_j, bi, bj, pi, ai, pj, aj, rj in joints:
        w("")
        w("[[joints]]")
        w(f'name = "{name_j}"')
        w('type = "revolute"')
        w(f'body_i = "{bi}"')
        w(f'body_j = "{bj}"')
        w(f"point_i = {fmt(pi)}")
        w(f"point_j = {fmt(pj)}")
        w(f"axis_i = {fmt(ai)}")
        w(f"axis_j = {fmt(aj)}")
        w(f"ref_i = {fmt(x)}")
        w(f"ref_j = {fmt(rj)}")
    w("")
    w("[[drivers]]")
    w('name = "motor"')
    w('joint = "J1"')
    w('motion = "rotation"')
    w(f"law = {{ start = {thetas[0]!r}, velocity = 1.0, acceleration = 0.0 }}")
    with open(os.path.join(HERE, f"{name}.toml"), "w") as f:
        f.write("\n".join(out) + "\n")


def write(name, title, a, b, alpha1, alpha2, theta0, step, steps):
    theta2 = closed_form(theta0, alpha1, alpha2)
    comment = [
        "Written by tests/redundancy/bennett.py (see its docstring): a Bennett linkage of four",
        f"revolutes, DH a = {a!r}, b = {b!r}, twists {math.degrees(alpha1):g}° and {math.degrees(alpha2):g}°,",
        "a / sin α1 = b / sin α2. Joint k's angle is the DH angle θk; the closed form is",
        "tan(θ1/2) tan(θ2/2) = sin((α2 + α1)/2) / sin((α2 − α1)/2), θ3 = −θ1, θ4 = −θ2.",
        f"J1 is driven at 1 rad/s from θ1 = {theta0!r} rad through a full turn in steps of",
        f"{math.degrees(step):g}°. Grübler counts 3·6 − 4·5 = −2 degrees of freedom; the mobility is 1 and 3 rows",
        "are redundant.",
    ]
    links = [(a, alpha1, 0.0), (b, alpha2, 0.0), (a, alpha1, 0.0), (b, alpha2, 0.0)]
    write_loop(name, title, comment, links, [theta0, theta2, -theta0, -theta2], step, steps)


DEG = math.pi / 180
A = (0.5, 0.5 * math.sin(75 * DEG) / math.sin(45 * DEG), 45 * DEG, 75 * DEG)
B = (1.0, math.sqrt(2.0), 45 * DEG, 90 * DEG)
# The starts and steps of issue 15 point 5: a full turn from each start in steps of 5° and of
# 20°. Every 5° grid lands exactly on θ1 = 0 and π (up to the rounding of t); of the 20° grids
# those from 0 and 180° do, those from 45°, 90° and 135° step over both.
STARTS = [0, 45, 90, 135, 180]
STEPS = [5, 20]
# (suffix, start angle, step, steps): more full turns, from −149° in steps of 1° (landing on 0
# and π) and from 1 rad in steps of 5° (landing on neither).
OTHERS = [("m149", -149 * DEG, 1 * DEG, 360), ("1rad", 1.0, 5 * DEG, 72)]


def grids():
    """(suffix, start, step, steps) of every description: `{start}_{step}` in degrees."""
    for start in STARTS:
        for step in STEPS:
            yield f"{start}_{step}", start * DEG, step * DEG, 360 // step
    yield from OTHERS


if __name__ == "__main__":
    for geometry, (a, b, alpha1, alpha2) in [("a", A), ("b", B)]:
        for suffix, theta0, step, steps in grids():
            write(
                f"bennett_{geometry}_{suffix}",
                f"Bennett linkage {geometry.upper()} from theta1 = {theta0:.6g} rad",
                a, b, alpha1, alpha2, theta0, step, steps,
            )
