#!/usr/bin/env python3
"""Drive folders from a third-party multibody vehicle model (dev tool).

The vehicle is the CommonRoad multi-body model "MB" (PyPI
`commonroad-vehicle-models`, `vehicle_dynamics_mb`): sprung mass with roll and
pitch, front and rear unsprung masses with their own roll, vertical tyre
springs, wheel spin states and the PAC2002 magic-formula tyres. This script
only drives it (route, speed profile, path-following steering), derives the
sensors from its states and adds the sensor and geometry effects of the
physics catalogue on top. See README.md.

    make_drives.py drive OUT --vehicle 2 --seed 1 [--effect ID[=VALUE|.PARAM=VALUE]]...
    make_drives.py suite OUT_DIR --seeds 5
"""

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from types import SimpleNamespace

import numpy as np
from scipy.integrate import solve_ivp

from vehiclemodels.init_mb import init_mb
from vehiclemodels.parameters_vehicle1 import parameters_vehicle1
from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
from vehiclemodels.parameters_vehicle3 import parameters_vehicle3
from vehiclemodels.vehicle_dynamics_mb import vehicle_dynamics_mb

TOOL_VERSION = "1"
# The package's parameter sets usable with MB (4 is a truck with a trailer).
VEHICLES = {
    1: ("ford_escort", parameters_vehicle1),
    2: ("bmw_320i", parameters_vehicle2),
    3: ("vw_vanagon", parameters_vehicle3),
}
RECORD_HZ = 200.0  # physics record (the wheel angle is integrated on it)
OUT_HZ = 100.0  # wheels, gyro, truth
GNSS_HZ = 10.0
TICKS_PER_REV = 96
G = 9.81

# Added effects: id -> typical parameters (first = main), as the catalogue and
# our own simulator name them.
TYPICAL = {
    "gyro_bias": {"b_deg_h": 200.0},
    "gyro_scale": {"s": 0.005},
    "gnss_latency": {"tau_s": 0.08},
    "gnss_lever_arm": {"x_m": 1.2, "y_m": 0.0},
    "track_width": {"rel": 0.02},
    "heading_bias": {"b_deg": 3.0, "a_deg": 0.0, "c_deg": 0.0},
    "radius_drift": {"d": 0.003, "time_constant_s": 600.0},
    "speed_radius_growth": {"k_v": 2.5e-6},
}
# Tyre physics of the multibody model: always present, sizes measured.
INHERENT = ["side_slip", "load_transfer_radius", "longitudinal_slip"]

# Sensor settings (written to truth.toml [sensors.*]).
SENSORS = {
    "gnss": {"rate_hz": GNSS_HZ, "white_sigma_m": 0.5, "gm_sigma_m": 0.5, "gm_tau_s": 60.0},
    "imu": {"rate_hz": OUT_HZ, "gz_sigma_rad_s": math.radians(0.1), "accel_sigma_m_s2": 0.05},
    "heading": {"rate_hz": GNSS_HZ, "sigma_deg": 2.0},
    "wheels": {"rate_hz": OUT_HZ, "ticks_per_rev": TICKS_PER_REV},
}
# Share of the tyre's static deflection change that shows in the effective
# rolling radius (radial tyres: about 0.1 near nominal load; MF-Tyre's
# effective-radius parameters give d r_e / d deflection ~ 0.1).
REFF_LOAD_FRACTION = 0.1


def params_of(vehicle_id):
    """The package's parameter set as a plain namespace (fast attribute access)."""

    def ns(d):
        if isinstance(d, dict):
            return SimpleNamespace(**{k: ns(v) for k, v in d.items()})
        return d

    return ns(dataclasses.asdict(VEHICLES[vehicle_id][1]()))


# ---------------------------------------------------------------- route


class Route:
    """A dense centre line (0.5 m spacing) with a speed profile and stops."""

    DS = 0.5

    def __init__(self, segments, stops):
        # segments: list of (length_m, curvature_1_m, vmax_m_s)
        xs, ys, th, ka, vl = [0.0], [0.0], [0.0], [0.0], [0.0]
        for length, kappa, vmax in segments:
            n = max(1, int(round(length / self.DS)))
            for _ in range(n):
                t0 = th[-1]
                t1 = t0 + kappa * self.DS
                tm = 0.5 * (t0 + t1)
                xs.append(xs[-1] + self.DS * math.cos(tm))
                ys.append(ys[-1] + self.DS * math.sin(tm))
                th.append(t1)
                ka.append(kappa)
                vl.append(vmax)
        self.x, self.y, self.th = np.array(xs), np.array(ys), np.array(th)
        self.kappa, self.vmax = np.array(ka), np.array(vl)
        self.s = np.arange(len(xs)) * self.DS
        self.stops = stops  # list of (index, duration_s), the last = end of the route
        self._profile()

    def _profile(self, a_lat=2.5, a_acc=1.5, a_dec=2.0):
        n = len(self.s)
        # curvature limit, looking a car length either side (steering lag)
        k = np.abs(self.kappa)
        kk = np.maximum.reduce([np.roll(k, i) for i in range(-8, 9)])
        v = np.minimum(self.vmax, np.sqrt(a_lat / np.maximum(kk, 1e-6)))
        v[0] = 0.0
        for i, _ in self.stops:
            v[min(i, n - 1)] = 0.0
        for i in range(1, n):
            v[i] = min(v[i], math.sqrt(v[i - 1] ** 2 + 2 * a_acc * self.DS))
        for i in range(n - 2, -1, -1):
            v[i] = min(v[i], math.sqrt(v[i + 1] ** 2 + 2 * a_dec * self.DS))
        self.v = v
        # feed-forward acceleration dv/dt = d(v^2/2)/ds
        self.a = np.gradient(0.5 * v * v, self.DS)

    def duration_estimate(self):
        vm = np.maximum(0.5 * (self.v[1:] + self.v[:-1]), 0.7)
        return float(np.sum(self.DS / vm)) + sum(d for _, d in self.stops)


def make_route(rng, target_s=540.0):
    """City (90-degree corners, stops, 30-50 km/h) then a ring road (long bends,
    60-90 km/h), then back into town to a final stop."""
    segs, stop_at = [], []  # stop_at: (segment index after which to stop, duration)

    def length_so_far():
        return sum(s[0] for s in segs)

    def estimate():
        r = Route(segs + [(20.0, 0.0, 8.0)], [(int(round(a / Route.DS)), d) for a, d in stops_s()])
        return r.duration_estimate()

    def stops_s():
        out, acc = [], 0.0
        for j, seg in enumerate(segs):
            acc += seg[0]
            for k, d in stop_at:
                if k == j:
                    out.append((acc, d))
        return out

    def city(until):
        while estimate() < until:
            v = rng.uniform(30, 50) / 3.6
            segs.append((rng.uniform(80, 220), 0.0, v))
            if rng.random() < 0.4:
                stop_at.append((len(segs) - 1, rng.uniform(5, 20)))
            r = rng.uniform(9, 15)
            sign = 1.0 if rng.random() < 0.5 else -1.0
            segs.append((0.5 * math.pi * r, sign / r, v))

    def ring(until):
        turn = 1.0 if rng.random() < 0.5 else -1.0
        while estimate() < until:
            v = rng.uniform(60, 90) / 3.6
            segs.append((rng.uniform(150, 400), 0.0, v))
            r = rng.uniform(max(180.0, v * v / 2.2), 450.0)
            ang = math.radians(rng.uniform(50, 120))
            sign = turn if rng.random() < 0.8 else -turn
            segs.append((ang * r, sign / r, v))

    city(0.45 * target_s)
    ring(0.85 * target_s)
    city(target_s - 15.0)
    segs.append((20.0, 0.0, 8.0))
    total = length_so_far()
    stops = [(int(round(a / Route.DS)), d) for a, d in stops_s()]
    stops.append((int(round(total / Route.DS)), 10.0))
    return Route(segs, stops)


# ---------------------------------------------------------------- driving


class Driver:
    """Speed profile tracking + Stanley path following at the front axle; the
    model's inputs are the steering rate and the acceleration."""

    def __init__(self, route, p):
        self.r, self.p = route, p
        self.hint = 0
        self.stop_index = len(route.s) - 1

    def nearest(self, px, py):
        r = self.r
        lo = max(0, self.hint - 40)
        hi = min(len(r.s), self.hint + 120)
        d = (r.x[lo:hi] - px) ** 2 + (r.y[lo:hi] - py) ** 2
        i = lo + int(np.argmin(d))
        self.hint = i
        return i

    def inputs(self, x):
        p, r = self.p, self.r
        psi, vx = x[4], x[3]
        c, s = math.cos(psi), math.sin(psi)
        fx, fy = x[0] + p.a * c, x[1] + p.a * s
        i = self.nearest(fx, fy)
        # project on the path's tangent at i (smooth between the path points)
        ct, st = math.cos(r.th[i]), math.sin(r.th[i])
        along = (fx - r.x[i]) * ct + (fy - r.y[i]) * st
        e = -(fx - r.x[i]) * st + (fy - r.y[i]) * ct - 0.5 * r.kappa[i] * along * along
        th_path = r.th[i] + r.kappa[i] * along
        he = math.atan2(math.sin(th_path - psi), math.cos(th_path - psi))
        lwb = p.a + p.b
        delta_des = he - math.atan2(1.2 * e, abs(vx) + 2.0) + math.atan(lwb * r.kappa[i])
        delta_des += 0.05 * (vx * r.kappa[i] - x[5])  # yaw-rate damping
        u0 = max(-0.4, min(0.4, 6.0 * (delta_des - x[2])))
        # speed: along the profile (rear axle's station); never past the coming stop
        sr = r.s[i] + along - lwb
        j = min(max(int(sr / r.DS), 0), len(r.s) - 2)
        f = min(max(sr / r.DS - j, 0.0), 1.0)
        vref = r.v[j] + f * (r.v[j + 1] - r.v[j])
        aff = r.a[j] + f * (r.a[j + 1] - r.a[j])
        u1 = aff + 1.2 * (vref - vx)
        if sr >= self.stop_index * r.DS:
            u1 = -2.0
        u1 = max(-4.0, min(2.5, u1))
        return [u0, u1], i


def simulate(vehicle_id, route_seed, verbose=True):
    """Drive the MB model along a seeded route; return the physics record."""
    rng = np.random.default_rng(10_000 + route_seed)
    p = params_of(vehicle_id)
    route = make_route(rng)
    drv = Driver(route, p)
    x = np.array(init_mb([route.x[0] + p.b, route.y[0], 0.0, 0.0, 0.0, 0.0, 0.0], p), float)
    # x[0:2] is the centre of mass; put the rear axle on the route's start
    t_now = 0.0
    ts, xs = [], []
    dt = 1.0 / RECORD_HZ
    v_go = 0.3  # below it the model is kinematic (0.1 m/s) or very stiff: we stop

    def hold(duration, xstate):
        nonlocal t_now
        xh = xstate.copy()
        for k in (3, 5, 7, 9, 10, 12, 14, 15, 17, 19, 20, 22, 23, 24, 25, 26):
            xh[k] = 0.0
        n = int(round(duration * RECORD_HZ))
        for _ in range(n):
            t_now += dt
            ts.append(t_now)
            xs.append(xh.copy())

    ts.append(0.0)
    xs.append(x.copy())
    hold(10.0, x)
    t0 = time.time()
    for k, (stop_i, stop_dur) in enumerate(route.stops):
        drv.stop_index = stop_i
        x[3] = v_go
        x[10] = 0.0
        for w in (23, 24, 25, 26):
            x[w] = v_go / p.R_w

        def rhs(t, xx):
            u, i = drv.inputs(xx)
            return vehicle_dynamics_mb(list(xx), u, p)

        def stopped(t, xx):
            return xx[3] - (v_go - 0.05)

        stopped.terminal = True
        stopped.direction = -1
        t_end = t_now + 900.0
        t_eval_start = t_now + dt
        sol = solve_ivp(
            rhs,
            (t_now, t_end),
            x,
            method="BDF",
            max_step=0.05,
            rtol=1e-5,
            atol=1e-6,
            dense_output=True,
            events=stopped,
        )
        # advance the nearest-point hint by the real trajectory, not trial calls
        t_stop = sol.t[-1]
        grid = np.arange(t_eval_start, t_stop + 1e-12, dt)
        if len(grid):
            y = sol.sol(grid)
            for j in range(len(grid)):
                ts.append(grid[j])
                xs.append(y[:, j].copy())
            t_now = grid[-1]
        x = sol.y[:, -1].copy()
        _, drv.hint = drv.inputs(x)
        if verbose:
            print(
                f"  leg {k + 1}/{len(route.stops)}: to {t_now:.0f} s, at station "
                f"{drv.hint * route.DS:.0f}/{stop_i * route.DS:.0f} m, {sol.nfev} model calls, "
                f"{time.time() - t0:.0f} s wall",
                file=sys.stderr,
            )
        hold(stop_dur, x)
    return {
        "t": np.array(ts),
        "x": np.array(xs),
        "vehicle_id": vehicle_id,
        "route_seed": route_seed,
        "route_length_m": float(route.s[-1]),
    }


def cached_simulation(cache_dir, vehicle_id, route_seed):
    os.makedirs(cache_dir, exist_ok=True)
    f = os.path.join(cache_dir, f"mb_v{vehicle_id}_r{route_seed}.npz")
    if os.path.exists(f):
        d = np.load(f)
        return {k: (d[k] if d[k].ndim else d[k].item()) for k in d.files}
    t0 = time.time()
    sim = simulate(vehicle_id, route_seed)
    sim["wall_s"] = time.time() - t0
    np.savez_compressed(f, **sim)
    return sim


# ---------------------------------------------------------------- sensors


def gauss_markov(rng, n, dt, sigma, tau):
    phi = math.exp(-dt / tau)
    q = sigma * math.sqrt(1 - phi * phi)
    out = np.empty(n)
    v = rng.normal(0, sigma)
    for i in range(n):
        out[i] = v
        v = phi * v + rng.normal(0, q)
    return out


def derive(sim, effects, noise_seed):
    """Everything a drive folder needs, from the physics record and the added
    effects. Returns (files: name -> (header, rows) or text, truth dict)."""
    p = params_of(int(sim["vehicle_id"]))
    t, X = sim["t"], sim["x"]
    rng = np.random.default_rng(noise_seed)
    psi, r, vx, vy = X[:, 4], X[:, 5], X[:, 3], X[:, 10]
    c, s = np.cos(psi), np.sin(psi)
    # rear-axle centre: the CoM back by b, and the rear unsprung mass's lateral
    # compliance offset (delta_y_r = sprung point minus unsprung lateral motion)
    rx = X[:, 0] - p.b * c + X[:, 28] * s
    ry = X[:, 1] - p.b * s - X[:, 28] * c

    # vertical tyre forces from the tyre springs (the model's definition)
    def fz(zu, phiu, track, side):
        return (zu + p.R_w * (np.cos(phiu) - 1) + side * 0.5 * track * np.sin(phiu)) * p.K_zt

    # The package labels its wheels L/R the other way round from their place:
    # its "left" wheel speed is v_x + T/2 * yaw rate and its yaw moment takes
    # its "left" wheel at body y = -T/2. We name the wheels by where they are
    # (y = +T/2 is left, ISO 8855 as the drive format), so its L is our right.
    Fz = {
        "fl": fz(X[:, 16], X[:, 13], p.T_f, +1),
        "fr": fz(X[:, 16], X[:, 13], p.T_f, -1),
        "rl": fz(X[:, 21], X[:, 18], p.T_r, +1),
        "rr": fz(X[:, 21], X[:, 18], p.T_r, -1),
    }
    spin = {"fl": X[:, 24], "fr": X[:, 23], "rl": X[:, 26], "rr": X[:, 25]}
    moving = vx > 0.5
    wear_rng = np.random.default_rng(20_000 + int(sim["route_seed"]))
    wear_mm = {w: float(wear_rng.uniform(0.5, 3.0)) for w in ("rl", "rr", "fl", "fr")}
    k_tyre = p.K_zt / REFF_LOAD_FRACTION  # r_eff = r0 - F_z / k_tyre
    r_static, r_eff, r0 = {}, {}, {}
    for w in Fz:
        fz0 = float(np.median(Fz[w][~moving])) if np.any(~moving) else float(np.median(Fz[w]))
        r_static[w] = p.R_w - wear_mm[w] / 1000.0
        r0[w] = r_static[w] + fz0 / k_tyre
        r_eff[w] = r0[w] - Fz[w] / k_tyre
    growth = np.ones_like(t)
    if "speed_radius_growth" in effects:
        growth *= 1 + effects["speed_radius_growth"]["k_v"] * vx * vx
    if "radius_drift" in effects:
        e = effects["radius_drift"]
        growth *= 1 + e["d"] * (1 - np.exp(-t / e["time_constant_s"]))
    # wheel angle: the model's rolling speed R_w*omega over the effective radius
    revs = {}
    for w in spin:
        rate = spin[w] * p.R_w / (r_eff[w] * growth) / (2 * math.pi)
        revs[w] = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])

    step = int(round(RECORD_HZ / OUT_HZ))
    io = np.arange(0, len(t), step)
    to = t[io]
    files = {}
    ticks = {w: np.floor(revs[w][io] * TICKS_PER_REV).astype(np.int64) for w in revs}
    files["wheels.csv"] = (
        "t_s,rl_ticks,rr_ticks,fl_ticks,fr_ticks",
        [to, ticks["rl"], ticks["rr"], ticks["fl"], ticks["fr"]],
    )
    files["truth.csv"] = ("t_s,x_m,y_m,yaw_rad", [to, rx[io], ry[io], psi[io]])
    # gyro
    gz = r[io].copy()
    if "gyro_scale" in effects:
        gz *= 1 + effects["gyro_scale"]["s"]
    if "gyro_bias" in effects:
        gz += math.radians(effects["gyro_bias"]["b_deg_h"]) / 3600.0
    gz += rng.normal(0, SENSORS["imu"]["gz_sigma_rad_s"], len(gz))
    # accelerometer at the CoM: body-frame kinematics plus gravity through roll
    dvx = np.gradient(vx, t)
    dvy = np.gradient(vy, t)
    ax = dvx - r * vy
    ay = dvy + r * vx + G * np.sin(X[:, 6])
    sa = SENSORS["imu"]["accel_sigma_m_s2"]
    files["imu.csv"] = (
        "t_s,gz_rad_s,ax_m_s2,ay_m_s2",
        [to, gz, ax[io] + rng.normal(0, sa, len(io)), ay[io] + rng.normal(0, sa, len(io))],
    )
    # GNSS (antenna at the rear-axle centre unless the lever arm is on)
    ig = np.arange(0, len(t), int(round(RECORD_HZ / GNSS_HZ)))
    lx = effects.get("gnss_lever_arm", {}).get("x_m", 0.0)
    ly = effects.get("gnss_lever_arm", {}).get("y_m", 0.0)
    gx = rx[ig] + c[ig] * lx - s[ig] * ly
    gy = ry[ig] + s[ig] * lx + c[ig] * ly
    sg = SENSORS["gnss"]
    n = len(ig)
    gx = gx + rng.normal(0, sg["white_sigma_m"], n) + gauss_markov(rng, n, 1 / GNSS_HZ, sg["gm_sigma_m"], sg["gm_tau_s"])
    gy = gy + rng.normal(0, sg["white_sigma_m"], n) + gauss_markov(rng, n, 1 / GNSS_HZ, sg["gm_sigma_m"], sg["gm_tau_s"])
    tg = t[ig] + effects.get("gnss_latency", {}).get("tau_s", 0.0)
    files["gnss.csv"] = ("t_s,x_m,y_m,sigma_m", [tg, gx, gy, np.full(n, sg["white_sigma_m"])])
    # compass
    yaw = psi[ig].copy()
    if "heading_bias" in effects:
        h = effects["heading_bias"]
        yaw += np.radians(h.get("a_deg", 0.0) + h.get("b_deg", 0.0) * np.sin(psi[ig]) + h.get("c_deg", 0.0) * np.cos(psi[ig]))
    sh = math.radians(SENSORS["heading"]["sigma_deg"])
    yaw += rng.normal(0, sh, n)
    yaw = np.arctan2(np.sin(yaw), np.cos(yaw))
    files["heading.csv"] = ("t_s,yaw_rad,sigma_rad", [t[ig], yaw, np.full(n, sh)])

    # ---- emergent tyre physics, measured on the drive (moving, v > 3 m/s)
    vrx = np.gradient(rx, t)
    vry = np.gradient(ry, t)
    v_ra = vrx * c + vry * s  # rear-axle speed along the body
    lat = -vrx * s + vry * c
    m = v_ra > 3.0
    a_y = v_ra * r
    a_x = np.gradient(v_ra, t)
    beta = np.arctan2(lat, v_ra)

    def slope(yv, xv, intercept=False):
        if intercept:
            A = np.vstack([xv, np.ones_like(xv)]).T
        else:
            A = xv[:, None]
        coef, res, *_ = np.linalg.lstsq(A, yv, rcond=None)
        pred = A @ coef
        ss = np.sum((yv - yv.mean()) ** 2)
        r2 = 1 - np.sum((yv - pred) ** 2) / ss if ss > 0 else 0.0
        return float(coef[0]), float(r2)

    k_beta, r2_beta = slope(beta[m], a_y[m])
    k_beta = -k_beta
    # load part of the radius: (r_L - r_R) / (r_L + r_R) = k_z a_y
    dr = (r_eff["rl"] - r_eff["rr"]) / (r_eff["rl"] + r_eff["rr"])
    k_z, r2_z = slope(dr[m], a_y[m], intercept=True)
    # what the wheels show: apparent circumference c = ground speed / rev rate
    half = 0.5 * p.T_r
    rate_l = np.gradient(revs["rl"], t)
    rate_r = np.gradient(revs["rr"], t)
    m2 = m & (rate_l > 0.5) & (rate_r > 0.5)
    with np.errstate(divide="ignore", invalid="ignore"):
        c_l = (v_ra - r * half) / rate_l
        c_r = (v_ra + r * half) / rate_r
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (c_l - c_r) / (c_l + c_r)
    k_z_app, r2_zapp = slope(ratio[m2], a_y[m2], intercept=True)
    # longitudinal slip of the rear axle: wheel speed = v (1 + k_s a_x)
    ws = 0.5 * (spin["rl"] + spin["rr"]) * p.R_w
    k_s, r2_s = slope((ws / np.maximum(v_ra, 1e-3) - 1)[m], a_x[m], intercept=True)
    a_y_abs = np.abs(a_y[m])
    measured = {
        "side_slip": {"k_beta": k_beta, "r2": r2_beta},
        "load_transfer_radius": {"k_z": k_z, "r2": r2_z, "k_z_apparent": k_z_app, "r2_apparent": r2_zapp},
        "longitudinal_slip": {"k_s": k_s, "r2": r2_s},
    }
    # drive-average effective circumference of each rear wheel (slip included)
    dist_l = np.sum(np.abs(v_ra - r * half)[:-1] * np.diff(t))
    dist_r = np.sum(np.abs(v_ra + r * half)[:-1] * np.diff(t))
    truth = {
        "track_width_m": float(p.T_r),
        "circumference_m": {w: 2 * math.pi * r_static[w] for w in ("rl", "rr", "fl", "fr")},
        "circumference_drive_mean_m": {"rl": float(dist_l / revs["rl"][-1]), "rr": float(dist_r / revs["rr"][-1])},
        "measured": measured,
        "wear_mm": wear_mm,
        "tyre": {
            "R_w_m": float(p.R_w),
            "K_zt_n_m": float(p.K_zt),
            "reff_load_fraction": REFF_LOAD_FRACTION,
            "k_z_tyre_n_m": float(k_tyre),
        },
        "stats": {
            "duration_s": float(t[-1]),
            "route_length_m": float(sim["route_length_m"]),
            "max_speed_m_s": float(vx.max()),
            "max_abs_a_y_m_s2": float(a_y_abs.max()) if len(a_y_abs) else 0.0,
            "p95_abs_a_y_m_s2": float(np.percentile(a_y_abs, 95)) if len(a_y_abs) else 0.0,
            "max_roll_deg": float(np.degrees(np.abs(X[:, 6]).max())),
            "rear_fz_range_n": [float(min(Fz["rl"].min(), Fz["rr"].min())), float(max(Fz["rl"].max(), Fz["rr"].max()))],
        },
    }
    return files, truth, p


# ---------------------------------------------------------------- writing


def fmt(v):
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(fmt(x) for x in v) + "]"
    raise TypeError(v)


def toml_text(d, prefix=""):
    lines, tables = [], []
    for k, v in d.items():
        if isinstance(v, dict):
            tables.append((k, v))
        else:
            lines.append(f"{k} = {fmt(v)}")
    out = "\n".join(lines) + ("\n" if lines else "")
    for k, v in tables:
        name = f"{prefix}{k}"
        sub = toml_text(v, name + ".")
        out += f"\n[{name}]\n" + sub
    return out


def write_csv(path, header, cols):
    cols = [np.asarray(c) for c in cols]
    with open(path, "w") as f:
        f.write(header + "\n")
        for row in zip(*cols):
            f.write(",".join(repr(float(v)) if isinstance(v, (float, np.floating)) else str(v) for v in row) + "\n")


def write_drive(out, sim, effects, noise_seed, label=""):
    os.makedirs(out, exist_ok=True)
    files, truth, p = derive(sim, effects, noise_seed)
    for name, (header, cols) in files.items():
        write_csv(os.path.join(out, name), header, cols)
    vid = int(sim["vehicle_id"])
    nominal_track = p.T_r / (1 + effects["track_width"]["rel"]) if "track_width" in effects else p.T_r
    vehicle = {
        "name": f"multibody {VEHICLES[vid][0]} (commonroad MB, route seed {int(sim['route_seed'])})",
        "track_width_m": float(nominal_track),
        "nominal_circumference_m": round(2 * math.pi * p.R_w, 2),
        "wheelbase_m": round(p.a + p.b, 4),
        "ticks_per_rev": float(TICKS_PER_REV),
    }
    with open(os.path.join(out, "vehicle.toml"), "w") as f:
        f.write(toml_text(vehicle))
    fx = {}
    for e, prm in effects.items():
        fx[e] = {k: float(v) for k, v in prm.items()}
    for e in INHERENT:
        main = {"side_slip": "k_beta", "load_transfer_radius": "k_z", "longitudinal_slip": "k_s"}[e]
        fx[e] = {main: truth["measured"][e][main]}
    doc = {
        "track_width_m": truth["track_width_m"],
        "nominal_track_width_m": float(nominal_track),
        "generator": "tools/multibody-drives/make_drives.py",
        "generator_version": TOOL_VERSION,
        "model": "commonroad-vehicle-models MB (vehicle_dynamics_mb, PAC2002 tyres)",
        "vehicle": VEHICLES[vid][0],
        "vehicle_id": vid,
        "route_seed": int(sim["route_seed"]),
        "noise_seed": int(noise_seed),
        "label": label,
        "added_effects": sorted(effects),
        "emergent_effects": INHERENT,
        "circumference_m": truth["circumference_m"],
        "circumference_drive_mean_m": truth["circumference_drive_mean_m"],
        "effects": fx,
        "measured": truth["measured"],
        "wear_mm": truth["wear_mm"],
        "tyre": truth["tyre"],
        "stats": truth["stats"],
        "sensors": SENSORS,
    }
    with open(os.path.join(out, "truth.toml"), "w") as f:
        f.write(toml_text(doc))
    return doc


def parse_effects(specs):
    eff = {}
    for spec in specs or []:
        key, _, val = spec.partition("=")
        eid, _, prm = key.partition(".")
        if eid not in TYPICAL:
            sys.exit(f"unknown or non-switchable effect `{eid}` (switchable: {', '.join(TYPICAL)}; "
                     f"{', '.join(INHERENT)} are the model's own)")
        cur = eff.setdefault(eid, dict(TYPICAL[eid]))
        if val in ("", "on"):
            continue
        name = prm or next(iter(TYPICAL[eid]))
        cur[name] = float(val)
    return eff


# ---------------------------------------------------------------- suite


def suite_cases(seeds):
    cases = []
    for seed in range(1, seeds + 1):
        vid = [1, 2, 3][seed % 3]
        for e in TYPICAL:
            cases.append((e, seed, vid, [e], {e: dict(TYPICAL[e])}))
        for a, b in [("gnss_latency", "side_slip"), ("track_width", "load_transfer_radius"), ("gnss_lever_arm", "side_slip")]:
            cases.append((f"{a}+{b}", seed, vid, [a, b], {a: dict(TYPICAL[a])}))
        cases.append(("null", seed, vid, [], {}))
        cases.append(("null-b", seed, vid, [], {}))
    return cases


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("drive", help="one drive folder")
    d.add_argument("out")
    d.add_argument("--vehicle", type=int, default=2, choices=sorted(VEHICLES))
    d.add_argument("--seed", type=int, default=1, help="route seed")
    d.add_argument("--noise-seed", type=int, default=None)
    d.add_argument("--effect", action="append", help="ID, ID=VALUE or ID.PARAM=VALUE (repeatable)")
    d.add_argument("--cache", default=None, help="physics cache folder (default OUT/../.mb-cache)")
    d.add_argument("--reff-load-fraction", type=float, default=REFF_LOAD_FRACTION,
                   help="share of the tyre deflection that moves the rolling radius (default 0.1)")
    s = sub.add_parser("suite", help="the concealed-effect suite")
    s.add_argument("out_dir")
    s.add_argument("--seeds", type=int, default=5)
    s.add_argument("--reff-load-fraction", type=float, default=REFF_LOAD_FRACTION,
                   help="share of the tyre deflection that moves the rolling radius (default 0.1)")
    a = ap.parse_args()
    globals()["REFF_LOAD_FRACTION"] = a.reff_load_fraction
    if a.cmd == "drive":
        cache = a.cache or os.path.join(os.path.dirname(os.path.abspath(a.out)), ".mb-cache")
        sim = cached_simulation(cache, a.vehicle, a.seed)
        ns = a.noise_seed if a.noise_seed is not None else a.seed
        doc = write_drive(a.out, sim, parse_effects(a.effect), ns)
        print(f"wrote {a.out}: {VEHICLES[a.vehicle][0]}, {doc['stats']['duration_s']:.0f} s, "
              f"{doc['stats']['route_length_m']:.0f} m, added {doc['added_effects']}, measured "
              + ", ".join(f"{k} {v}" for k, v in doc["effects"].items() if k in INHERENT))
    else:
        cache = os.path.join(a.out_dir, ".mb-cache")
        manifest = []
        for i, (label, seed, vid, truth_ids, eff) in enumerate(suite_cases(a.seeds)):
            t0 = time.time()
            sim = cached_simulation(cache, vid, seed)
            name = f"s{seed}-{label}"
            noise = seed * 1000 + (1 if label == "null-b" else 0)
            doc = write_drive(os.path.join(a.out_dir, name), sim, eff, noise, label)
            manifest.append({"drive": name, "label": label, "seed": seed, "vehicle": VEHICLES[vid][0],
                             "truth": truth_ids, "allowed": INHERENT, "added": sorted(eff),
                             "effects": doc["effects"]})
            print(f"{name}: {VEHICLES[vid][0]}, {time.time() - t0:.1f} s", file=sys.stderr)
            with open(os.path.join(a.out_dir, "manifest.json"), "w") as f:
                json.dump(manifest, f, indent=1)


if __name__ == "__main__":
    main()
