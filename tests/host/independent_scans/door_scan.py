#!/usr/bin/python3
"""An independent door-scan generator for testing `dentmark detect`.

It shares no code and no modelling choice with sim/scan (DoorPanel, SLS scan): only the
output formats are the project's (binary PLY, truth schema "dentmark.truth/1").

Surface (panel frame: u along the door, v up, w out of the panel; metres):
  * base: a uniform bicubic B-spline height field over a 7 x 6 control grid, its control
    heights taken from two cylinders (radii drawn per seed), a tilt, and random bulges;
  * character lines: straight or slightly bowed lines across the whole panel, each a
    quintic smooth step of height 2-4 mm over a width of 10-14 mm (footprint: the step);
  * a handle: a rounded box 110-130 x 26-34 mm, 10-14 mm proud, walls 6-9 mm wide;
  * a window opening (rounded rectangle) and the panel's edges, both rolled off over 8 mm;
  * defects: Gaussian, raised-cosine or spherical-cap dents and bumps, added along w.
Scanner: a pinhole sensor 0.8-1.1 m away, tilted up to 15 deg about two axes; each pixel's
ray is intersected with the height field (fixed-point iteration along the ray). Noise
along the ray (growing at grazing incidence), per-pixel dropouts, mixed-pixel artefacts on
depth edges, flying pixels thrown along their ray. Meshed on the pixel grid.

Truth: dentmark.truth/1; each defect carries extra fields the project's reader ignores:
  profile, feature (what it was placed beside), gap (m, from its rim to that feature's
  footprint; negative: on it), band (a label for the gap).
"""

import argparse
import json
import math
import struct
import sys

import numpy as np

BANDS = [("3-6mm", 0.003, 0.006), ("6-12mm", 0.006, 0.012), ("12-25mm", 0.012, 0.025), ("25-50mm", 0.025, 0.050)]
ROLL = 0.008  # m, roll-off radius at the panel's edges and the window's


def smootherstep(t):
    t = np.clip(t, 0.0, 1.0)
    return t * t * t * (t * (6.0 * t - 15.0) + 10.0)


def rounded_box_sdf(u, v, cu, cv, hu, hv, r):
    """Signed distance to a rounded rectangle centred (cu, cv), half sizes hu, hv (negative inside)."""
    qu = np.abs(u - cu) - (hu - r)
    qv = np.abs(v - cv) - (hv - r)
    return np.hypot(np.maximum(qu, 0), np.maximum(qv, 0)) + np.minimum(np.maximum(qu, qv), 0) - r


def bspline_basis(t):
    """Uniform cubic B-spline basis weights for local parameter t in [0, 1)."""
    t2, t3 = t * t, t * t * t
    return [(1 - 3 * t + 3 * t2 - t3) / 6, (4 - 6 * t2 + 3 * t3) / 6, (1 + 3 * t + 3 * t2 - 3 * t3) / 6, t3 / 6]


class Door:
    def __init__(self, rng, width, height, n_lines, line_angle, handle, window):
        self.W, self.H = width, height
        # Base: control heights of a B-spline patch (control grid spans past the panel).
        nu, nv = 7, 6
        self.nu, self.nv = nu, nv
        ru, rv = rng.uniform(2.0, 4.5), rng.uniform(1.2, 2.5)
        self.tilt = rng.uniform(-0.08, 0.08, size=2)
        cu = np.linspace(-1.5, nu - 2.5, nu) / (nu - 3) * width  # control positions (u)
        cv = np.linspace(-1.5, nv - 2.5, nv) / (nv - 3) * height
        CU, CV = np.meshgrid(cu, cv, indexing="ij")
        z = -((CU - width / 2) ** 2) / (2 * ru) - ((CV - height / 2) ** 2) / (2 * rv)
        z += self.tilt[0] * CU + self.tilt[1] * CV
        z += rng.normal(0, 0.003, size=z.shape)  # bulges a few mm
        self.ctrl = z
        self.radii = (ru, rv)
        # Character lines: (point, unit normal, height, width, bow).
        self.lines = []
        for k in range(n_lines):
            ang = line_angle + rng.uniform(-0.05, 0.05)
            t = np.array([math.cos(ang), math.sin(ang)])
            n = np.array([-t[1], t[0]])
            # Lines spread across the panel, through its lower and middle part.
            frac = (k + 1) / (n_lines + 1)
            centre = np.array([width / 2, height / 2])
            offset = (frac - 0.5) * (0.55 * min(width, height) if abs(n[1]) > 0.5 else 0.6 * width)
            p0 = centre + n * offset - np.array([0.0, 0.12 * height]) * (abs(n[1]) > 0.5)
            h = rng.uniform(0.002, 0.004) * rng.choice([-1.0, 1.0])
            w = rng.uniform(0.010, 0.014)
            bow = rng.uniform(-0.15, 0.15)  # 1/m: a gentle arc
            self.lines.append((p0, n, t, h, w, bow))
        self.handle = None
        if handle:
            self.handle = (0.70 * width, 0.55 * height, rng.uniform(0.055, 0.065), rng.uniform(0.013, 0.017),
                           rng.uniform(0.010, 0.014), rng.uniform(0.006, 0.009))
        self.window = (0.12 * width, 0.88 * width, 0.72 * height, 0.95 * height) if window else None
        self.defects = []  # dicts: u, v, a (radius), h, profile

    # --- geometry -------------------------------------------------------------------
    def base(self, u, v):
        su = u / self.W * (self.nu - 3) + 1.5
        sv = v / self.H * (self.nv - 3) + 1.5
        iu = np.clip(np.floor(su).astype(int), 1, self.nu - 3)
        iv = np.clip(np.floor(sv).astype(int), 1, self.nv - 3)
        bu = bspline_basis(su - iu)
        bv = bspline_basis(sv - iv)
        out = np.zeros_like(u)
        for a in range(4):
            for b in range(4):
                out += bu[a] * bv[b] * self.ctrl[np.clip(iu - 1 + a, 0, self.nu - 1), np.clip(iv - 1 + b, 0, self.nv - 1)]
        return out

    def line_offset(self, line, u, v):
        p0, n, t, h, w, bow = line
        du, dv = u - p0[0], v - p0[1]
        along = du * t[0] + dv * t[1]
        return du * n[0] + dv * n[1] - 0.5 * bow * along * along

    def handle_sdf(self, u, v):
        cu, cv, hu, hv, hh, ww = self.handle
        return rounded_box_sdf(u, v, cu, cv, hu, hv, min(hv, 0.012))

    def window_sdf(self, u, v):
        """Distance outside the opening (negative inside it)."""
        u0, u1, v0, v1 = self.window
        return rounded_box_sdf(u, v, (u0 + u1) / 2, (v0 + v1) / 2, (u1 - u0) / 2, (v1 - v0) / 2, 0.04)

    def edge_distance(self, u, v):
        d = np.minimum(np.minimum(u, self.W - u), np.minimum(v, self.H - v))
        if self.window is not None:
            d = np.minimum(d, self.window_sdf(u, v))
        return d

    def nominal(self, u, v):
        z = self.base(u, v)
        for line in self.lines:
            p0, n, t, h, w, bow = line
            z = z + h * smootherstep(self.line_offset(line, u, v) / w + 0.5)
        if self.handle is not None:
            cu, cv, hu, hv, hh, ww = self.handle
            z = z + hh * smootherstep(-self.handle_sdf(u, v) / ww)
        d = np.maximum(self.edge_distance(u, v), 0.0)
        roll = np.where(d < ROLL, ROLL - np.sqrt(np.maximum(ROLL * ROLL - (ROLL - d) ** 2, 0.0)), 0.0)
        return z - roll

    def defect_height(self, d, u, v):
        r = np.hypot(u - d["u"], v - d["v"])
        a, h = d["a"], d["h"]
        inside = r < a
        if d["profile"] == "cosine":
            f = 0.5 * (1 + np.cos(np.pi * np.minimum(r / a, 1.0)))
        elif d["profile"] == "gaussian":
            s = a / 2.5
            e0 = math.exp(-(a * a) / (2 * s * s))
            f = (np.exp(-(r * r) / (2 * s * s)) - e0) / (1 - e0)
        else:  # spherical cap of chord 2a and height |h|
            R = (a * a + h * h) / (2 * abs(h))
            f = (np.sqrt(np.maximum(R * R - r * r, 0.0)) - (R - abs(h))) / abs(h)
        return np.where(inside, h * f, 0.0)

    def surface(self, u, v):
        z = self.nominal(u, v)
        for d in self.defects:
            near = (np.abs(u - d["u"]) < d["a"]) & (np.abs(v - d["v"]) < d["a"])
            if near.any():
                z[near] += self.defect_height(d, u[near], v[near])
        return z

    def on_panel(self, u, v):
        return (u >= 0) & (u <= self.W) & (v >= 0) & (v <= self.H) & (self.edge_distance(u, v) >= 0)

    def normal(self, u, v):
        e = 1e-5
        U, V = np.array([u - e, u + e, u, u]), np.array([v, v, v - e, v + e])
        z = self.nominal(U, V)
        n = np.array([-(z[1] - z[0]) / (2 * e), -(z[3] - z[2]) / (2 * e), 1.0])
        return n / np.linalg.norm(n)

    # Rim-to-footprint gaps of a disc (centre, radius) to each feature (m; negative: overlaps).
    def gaps(self, u, v, a):
        out = {}
        for k, line in enumerate(self.lines):
            out["line%d" % k] = abs(float(self.line_offset(line, np.array(u), np.array(v)))) - line[4] / 2 - a
        if self.handle is not None:
            out["handle"] = float(self.handle_sdf(np.array(u), np.array(v))) - a
        out["edge"] = float(np.minimum(np.minimum(u, self.W - u), np.minimum(v, self.H - v))) - ROLL - a
        if self.window is not None:
            out["window"] = float(self.window_sdf(np.array(u), np.array(v))) - ROLL - a
        return out


# --- defect placement -------------------------------------------------------------------
def draw_defect(rng, args):
    a = 0.5 * rng.uniform(args.min_diameter, args.max_diameter)
    mag = args.min_depth * (args.max_depth / args.min_depth) ** rng.uniform()
    return {"a": a, "h": mag * rng.choice([-1.0, 1.0]), "profile": rng.choice(["gaussian", "cosine", "cap"])}


def clear_of_others(door, u, v, a):
    return all(math.hypot(u - d["u"], v - d["v"]) > a + d["a"] + 0.015 for d in door.defects)


def feature_point(rng, door, feature):
    """A point on the boundary of a feature's footprint and the outward unit direction there."""
    if feature.startswith("line"):
        p0, n, t, h, w, bow = door.lines[int(feature[4:])]
        for _ in range(200):
            s = rng.uniform(-1.0, 1.0)
            q = p0 + t * s
            if 0.12 < q[0] < door.W - 0.12 and 0.12 < q[1] < door.H - 0.12:
                q = q + n * (0.5 * bow * s * s)
                side = rng.choice([-1.0, 1.0])
                return q + side * n * (w / 2), side * n, q
        return None
    if feature == "handle":
        cu, cv, hu, hv, hh, ww = door.handle
        ang = rng.uniform(0, 2 * math.pi)
        d = np.array([math.cos(ang), math.sin(ang)])
        # March out from the centre to the footprint's boundary.
        for s in np.arange(0.0, 0.2, 0.0002):
            q = np.array([cu, cv]) + d * s
            if door.handle_sdf(np.array(q[0]), np.array(q[1])) >= 0:
                return q, d, q
        return None
    if feature == "window":
        u0, u1, v0, v1 = door.window
        q = np.array([rng.uniform(u0 + 0.06, u1 - 0.06), v0 - ROLL])
        return q, np.array([0.0, -1.0]), q
    # edge: one of the outer edges
    side = rng.integers(4)
    if side == 0:
        q, d = np.array([ROLL, rng.uniform(0.1, door.H * 0.6)]), np.array([1.0, 0.0])
    elif side == 1:
        q, d = np.array([door.W - ROLL, rng.uniform(0.1, door.H * 0.6)]), np.array([-1.0, 0.0])
    else:
        q, d = np.array([rng.uniform(0.1, door.W - 0.1), ROLL]), np.array([0.0, 1.0])
    return q, d, q


def place_beside(rng, door, args, features, bands, on_line=0):
    """Defects beside the named features in each band; on_line defects centred on lines."""
    placed = []
    jobs = [(f, b) for f in features for b in bands]
    jobs += [(f, None) for f in features if f.startswith("line") for _ in range(on_line)]
    for feature, band in jobs:
        for _ in range(400):
            d = draw_defect(rng, args)
            fp = feature_point(rng, door, feature)
            if fp is None:
                continue
            q, out_dir, centre_line = fp
            if band is None:
                c = centre_line
                target = None
            else:
                gap = rng.uniform(band[1], band[2])
                c = q + out_dir * (gap + d["a"])
                target = gap
            u, v = float(c[0]), float(c[1])
            if not door.on_panel(np.array(u), np.array(v)):
                continue
            gaps = door.gaps(u, v, d["a"])
            own = gaps[feature]
            others = [g for k, g in gaps.items() if k != feature]
            if band is not None and not (band[1] - 1e-4 <= own < band[2] + 1e-4):
                continue
            if others and min(others) < 0.025:  # clear of every other feature
                continue
            if not clear_of_others(door, u, v, d["a"]):
                continue
            d.update(u=u, v=v, feature=feature, gap=own if band is not None else -d["a"],
                     band=band[0] if band is not None else "on")
            door.defects.append(d)
            placed.append(d)
            break
    return placed


def place_free(rng, door, args, count, min_gap):
    for _ in range(count):
        for _ in range(2000):
            d = draw_defect(rng, args)
            u, v = rng.uniform(0, door.W), rng.uniform(0, door.H)
            if not door.on_panel(np.array(u), np.array(v)):
                continue
            gaps = door.gaps(u, v, d["a"])
            k = min(gaps, key=gaps.get)
            if gaps[k] < min_gap or not clear_of_others(door, u, v, d["a"]):
                continue
            d.update(u=u, v=v, feature=k, gap=gaps[k], band="free")
            door.defects.append(d)
            break


# --- scanner ----------------------------------------------------------------------------
def rotation(ax, ay):
    cx, sx, cy, sy = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    return Rx @ Ry


def scan(rng, door, args):
    W, H = door.W, door.H
    standoff = rng.uniform(0.8, 1.1)
    ax, ay = np.radians(rng.uniform(-15, 15, size=2))
    centre = np.array([W / 2, H / 2, float(door.nominal(np.array(W / 2), np.array(H / 2)))])
    # Sensor frame 'sls': z along the optical axis towards the panel, x right, y down.
    R_panel_sls = rotation(ax, ay) @ np.diag([1.0, -1.0, -1.0])  # columns: sls axes in the panel frame
    origin = centre - R_panel_sls[:, 2] * standoff
    # Pixel pitch: the requested spacing on the panel at its centre.
    f = standoff / args.spacing
    corners = np.array([[0, 0], [W, 0], [0, H], [W, H]])
    pts = np.c_[corners, np.full(4, centre[2])] - origin
    cam = pts @ R_panel_sls
    xs, ys = cam[:, 0] / cam[:, 2] * f, cam[:, 1] / cam[:, 2] * f
    x0, x1 = int(math.floor(xs.min())) - 4, int(math.ceil(xs.max())) + 4
    y0, y1 = int(math.floor(ys.min())) - 4, int(math.ceil(ys.max())) + 4
    px, py = np.meshgrid(np.arange(x0, x1 + 1, dtype=float), np.arange(y0, y1 + 1, dtype=float))
    rows, cols = px.shape
    d_cam = np.stack([px.ravel() / f, py.ravel() / f, np.ones(px.size)], axis=1)
    d_cam /= np.linalg.norm(d_cam, axis=1, keepdims=True)
    d = d_cam @ R_panel_sls.T  # ray directions in the panel frame
    # Ray against the height field: t <- t - (w(t) - z(u, v)) / d_w, a fixed-point
    # iteration that converges where the surface's slope along the ray is under 1; damped
    # after six steps for the few rays left (a handle's steep walls). Converged rays stop.
    t = (centre[2] - origin[2]) / d[:, 2]
    active = np.arange(len(t))
    with np.errstate(over="ignore", invalid="ignore"):
        for it in range(40):
            p = origin + d[active] * t[active, None]
            step = (p[:, 2] - door.surface(p[:, 0], p[:, 1])) / d[active, 2]
            t[active] -= (1.0 if it < 6 else 0.5) * step
            active = active[np.abs(step) > 1e-10]
            if active.size == 0:
                break
        p = origin + d * t[:, None]
        resid = np.abs(p[:, 2] - door.surface(p[:, 0], p[:, 1]))
    valid = door.on_panel(p[:, 0], p[:, 1]) & (resid < 1e-6)
    clean = p.copy()
    # Noise along the ray, larger at grazing incidence.
    n_est = np.stack([np.zeros(len(p)), np.zeros(len(p)), np.ones(len(p))], axis=1)
    cos_inc = np.abs(np.sum(-d * n_est, axis=1))
    sigma = args.noise * (1.0 + 0.5 * (1.0 - cos_inc))
    t_noisy = t + rng.normal(0.0, 1.0, size=len(t)) * sigma
    # Mixed pixels on depth edges (the panel's outline, the window): a pixel whose
    # 4-neighbour sees no panel is pulled behind. (Before the dropouts: a pixel that
    # returned nothing is no depth edge.)
    grid = valid.reshape(rows, cols).copy()
    edge = np.zeros_like(grid)
    edge[1:, :] |= ~grid[:-1, :]
    edge[:-1, :] |= ~grid[1:, :]
    edge[:, 1:] |= ~grid[:, :-1]
    edge[:, :-1] |= ~grid[:, 1:]
    edge = (edge & grid).ravel()
    # Per-pixel dropouts.
    valid &= rng.uniform(size=len(t)) >= args.dropout_rate
    mixed = valid & edge & (rng.uniform(size=len(t)) < args.edge_artefacts)
    t_noisy[mixed] += rng.uniform(0.0002, 0.003, size=int(mixed.sum()))
    # Flying pixels: isolated, thrown along their own ray.
    flying = valid & (rng.uniform(size=len(t)) < args.flying)
    t_noisy[flying] += rng.uniform(args.flying_min, args.flying_max, size=int(flying.sum())) * \
        rng.choice([-1.0, 1.0], size=int(flying.sum()))
    p = origin + d * t_noisy[:, None]
    # Mesh on the pixel grid; no triangle across a depth jump.
    idx = np.full(rows * cols, -1, dtype=np.int64)
    idx[valid] = np.arange(int(valid.sum()))
    I = idx.reshape(rows, cols)
    a, b, c, e = I[:-1, :-1], I[:-1, 1:], I[1:, :-1], I[1:, 1:]
    tris = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, e], -1).reshape(-1, 3)])
    tris = tris[(tris >= 0).all(axis=1)]
    P = clean[valid]
    Q = p[valid]
    e1 = np.linalg.norm(P[tris[:, 0]] - P[tris[:, 1]], axis=1)
    e2 = np.linalg.norm(P[tris[:, 1]] - P[tris[:, 2]], axis=1)
    e3 = np.linalg.norm(P[tris[:, 2]] - P[tris[:, 0]], axis=1)
    tris = tris[np.maximum(np.maximum(e1, e2), e3) < 5 * args.spacing]
    # Area of the surface itself (noise-free positions).
    area = 0.5 * np.linalg.norm(np.cross(P[tris[:, 1]] - P[tris[:, 0]], P[tris[:, 2]] - P[tris[:, 0]]), axis=1).sum()
    # Into the sensor frame; triangles face the sensor.
    V = (Q - origin) @ R_panel_sls
    nrm = np.cross(V[tris[:, 1]] - V[tris[:, 0]], V[tris[:, 2]] - V[tris[:, 0]])
    flip = np.sum(nrm * V[tris[:, 0]], axis=1) > 0
    tris[flip] = tris[flip][:, [0, 2, 1]]
    if args.shuffle:
        perm = rng.permutation(len(V))
        inv = np.empty_like(perm)
        inv[perm] = np.arange(len(perm))
        V = V[perm]
        tris = inv[tris]
        tris = tris[rng.permutation(len(tris))]
    T = np.eye(4)  # T_sls_panel
    T[:3, :3] = R_panel_sls.T
    T[:3, 3] = -R_panel_sls.T @ origin
    info = {"standoff": standoff, "tilt_deg": [math.degrees(ax), math.degrees(ay)], "pixels": [cols, rows],
            "flying_pixels": int(flying.sum()), "mixed_pixels": int(mixed.sum())}
    return V.astype(np.float32), tris.astype(np.int32), area, T, info


def write_ply(path, V, tris):
    with open(path, "wb") as fh:
        fh.write(("ply\nformat binary_little_endian 1.0\ncomment independent door_scan.py\n"
                  "element vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
                  "element face %d\nproperty list uchar int vertex_indices\nend_header\n"
                  % (len(V), len(tris))).encode())
        fh.write(np.ascontiguousarray(V, dtype="<f4").tobytes())
        rec = np.zeros(len(tris), dtype=[("n", "u1"), ("i", "<i4", 3)])
        rec["n"] = 3
        rec["i"] = tris
        fh.write(rec.tobytes())


def truth_json(door, area, T, args, info):
    def sls(u, v, z):
        return (T[:3, :3] @ np.array([u, v, z]) + T[:3, 3]).tolist()

    defects = []
    for k, d in enumerate(door.defects):
        n = door.normal(d["u"], d["v"])
        z = float(door.surface(np.array([d["u"]]), np.array([d["v"]]))[0])
        defects.append({"id": k + 1, "class": "dent" if d["h"] < 0 else "bump", "position": sls(d["u"], d["v"], z),
                        "normal": (T[:3, :3] @ n).tolist(), "diameter": 2 * d["a"], "height": d["h"] * float(n[2]),
                        "profile": str(d["profile"]), "feature": d["feature"], "gap": d["gap"], "band": d["band"]})
    features = []

    def feature(name, radius, pts):
        pts = [(u, v) for u, v in pts if 0 <= u <= door.W and 0 <= v <= door.H]
        if pts:
            U, Vv = np.array([p[0] for p in pts]), np.array([p[1] for p in pts])
            Z = door.nominal(U, Vv)
            features.append({"name": name, "radius": radius,
                             "points": [sls(u, v, z) for u, v, z in zip(U, Vv, Z)]})

    for k, (p0, n, t, h, w, bow) in enumerate(door.lines):
        s = np.arange(-2.0, 2.0, 0.01)
        feature("line%d" % k, w / 2 + 0.01, [tuple(p0 + t * x + n * 0.5 * bow * x * x) for x in s])
    if door.handle is not None:
        cu, cv, hu, hv, hh, ww = door.handle
        feature("handle", hv + 0.01, [(cu + x, cv) for x in np.arange(-hu + hv, hu - hv + 1e-9, 0.01)])
    per = np.arange(0, 1, 0.01 / (2 * (door.W + door.H)))
    feature("border", 0.02, [(x * door.W, 0.0) for x in per] + [(x * door.W, door.H) for x in per] +
            [(0.0, x * door.H) for x in per] + [(door.W, x * door.H) for x in per])
    if door.window is not None:
        u0, u1, v0, v1 = door.window
        feature("window", 0.02, [(x, v0) for x in np.arange(u0, u1, 0.01)] + [(x, v1) for x in np.arange(u0, u1, 0.01)])
    gen = {"name": "tests/host/independent_scans/door_scan.py", "seed": args.seed, "spacing": args.spacing,
           "noise": args.noise, "flying": args.flying, "dropout_rate": args.dropout_rate,
           "layout": args.layout, "radii": list(door.radii), "T_sls_panel": T.tolist(),
           "panel_size": [door.W, door.H]}
    gen.update(info)
    return {"schema": "dentmark.truth/1", "units": "m", "frame": "sls", "panel_area": float(area),
            "generator": gen, "defects": defects, "features": features}


LAYOUTS = {
    # Defects beside every design feature, in every band from its footprint.
    "features": dict(lines=1, handle=True, window=True),
    # Defects beside and on character lines (2 lines, one direction per seed).
    "lines": dict(lines=2, handle=False, window=False),
    # Free defects (coarse and flying-pixel classes); the paper's bump with --paper-bump.
    "free": dict(lines=1, handle=True, window=True),
}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, help="binary PLY (metres, sensor frame)")
    ap.add_argument("--truth", required=True, help="truth JSON (dentmark.truth/1)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--layout", choices=sorted(LAYOUTS), default="features")
    ap.add_argument("--width", type=float, default=0.9)
    ap.add_argument("--height", type=float, default=0.7)
    ap.add_argument("--spacing", type=float, default=0.0006)
    ap.add_argument("--noise", type=float, default=20e-6, help="1 sigma along the ray (m)")
    ap.add_argument("--dropout-rate", type=float, default=0.001)
    ap.add_argument("--edge-artefacts", type=float, default=0.3, help="share of edge pixels pulled behind")
    ap.add_argument("--flying", type=float, default=0.0, help="share of pixels thrown along their ray")
    ap.add_argument("--flying-min", type=float, default=0.001)
    ap.add_argument("--flying-max", type=float, default=0.010)
    ap.add_argument("--min-diameter", type=float, default=0.009)
    ap.add_argument("--max-diameter", type=float, default=0.025)
    ap.add_argument("--min-depth", type=float, default=1e-4)
    ap.add_argument("--max-depth", type=float, default=1e-3)
    ap.add_argument("--defects", type=int, default=8, help="free defects (layout free)")
    ap.add_argument("--on-line", type=int, default=2, help="defects centred on each character line")
    ap.add_argument("--paper-bump", action="store_true", help="add the paper's 9 mm wide, 11 mm high bump")
    ap.add_argument("--shuffle", action="store_true")
    args = ap.parse_args(argv)
    if not (1e-4 <= args.spacing <= 0.02 and 0 <= args.noise < 0.005 and 0 <= args.flying <= 0.05):
        ap.error("spacing must be in [0.1, 20] mm, noise in [0, 5) mm, flying in [0, 0.05]")
    if not (0 < args.min_diameter <= args.max_diameter and 0 < args.min_depth <= args.max_depth):
        ap.error("defect size ranges must be positive and ordered")
    rng = np.random.default_rng(args.seed)
    lay = LAYOUTS[args.layout]
    angle = float(rng.choice([0.0, 0.26, -0.26, 0.52, -0.52, math.pi / 2 - 0.1]))
    if args.layout == "features":
        angle = float(rng.uniform(-0.12, 0.12))
    door = Door(rng, args.width, args.height, lay["lines"], angle, lay["handle"], lay["window"])
    line_names = ["line%d" % k for k in range(len(door.lines))]
    if args.layout == "features":
        place_beside(rng, door, args, ["handle", "window", "edge"] + line_names, BANDS)
    elif args.layout == "lines":
        place_beside(rng, door, args, line_names, BANDS, on_line=args.on_line)
    else:
        if args.paper_bump:
            for _ in range(1000):
                u, v = rng.uniform(0.1, door.W - 0.1), rng.uniform(0.1, door.H - 0.1)
                gaps = door.gaps(u, v, 0.0045)
                if min(gaps.values()) > 0.03 and door.on_panel(np.array(u), np.array(v)):
                    door.defects.append({"u": u, "v": v, "a": 0.0045, "h": 0.011, "profile": "cosine",
                                         "feature": min(gaps, key=gaps.get), "gap": min(gaps.values()),
                                         "band": "paper"})
                    break
        place_free(rng, door, args, args.defects, 0.025)
    V, tris, area, T, info = scan(rng, door, args)
    write_ply(args.out, V, tris)
    with open(args.truth, "w") as fh:
        json.dump(truth_json(door, area, T, args, info), fh, indent=1)
        fh.write("\n")
    print("%s: %d vertices, %d triangles, %d planted defects, %.3f m²" % (args.out, len(V), len(tris),
                                                                          len(door.defects), area))
    return 0


if __name__ == "__main__":
    sys.exit(main())
