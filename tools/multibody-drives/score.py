#!/usr/bin/env python3
"""Score `calibrator diagnose` on a suite written by `make_drives.py suite`.

    score.py OUT_DIR [--calibrator PATH] [--rerun]

Runs `nice -n 10 calibrator diagnose DRIVE --json DRIVE/diagnosis.json` on each
drive of OUT_DIR/manifest.json, one at a time (kept when present unless
--rerun), and prints a table per effect; also writes OUT_DIR/score.md.

Scoring (as services/calibrator/benches/diagnose_suite.rs does): a drive's
targets are its added effects plus, in the pairs, the tyre effect named in
the pair; the model's own tyre physics (side_slip, load_transfer_radius,
longitudinal_slip) is present on every drive and may be found anywhere
("allowed"). Detected = the target id is among the findings; attributed =
detected and no id found outside targets + allowed; a wrong name = an id
outside targets + allowed; a false discovery on a null drive = the same there.
The multibody tyres of the rear-driven cars also have a speed growth of
their own, which make_drives does not record: it counts as allowed on a
drive whose wheels show at least OWN_GROWTH_ALLOWED against the truth
(`effective_speed_growth`, 0.4 of the catalogue's typical k_v).
"""

import argparse
import hashlib
import json
import math
import os
import subprocess
import sys
import time
from collections import OrderedDict, defaultdict

DEFAULT_CAL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "target", "release", "calibrator")


# The wheels' own speed growth (k_v, per (m/s)^2) from which a drive holds
# it as physics: 0.4 of the catalogue's typical 2.5e-6.
OWN_GROWTH_ALLOWED = 1.0e-6


def allowed_on(case, drive):
    """The ids that may be found on `drive` beyond its targets: the model's
    own tyre physics of the manifest, and the speed growth where the wheels
    show one of their own."""
    allowed = list(case["allowed"])
    if "speed_radius_growth" not in case["truth"] and "speed_radius_growth" not in allowed:
        own = (effective_speed_growth(drive) or {}).get("k_v")
        if own is not None and own >= OWN_GROWTH_ALLOWED:
            allowed.append("speed_radius_growth")
    return allowed


def run(cal, drive, rerun, extra=(), tag=""):
    out = os.path.join(drive, f"diagnosis{tag}.json")
    tfile = os.path.join(drive, f"diagnosis{tag}.time")
    if os.path.exists(out) and os.path.exists(tfile) and not rerun:
        return json.load(open(out)), float(open(tfile).read())
    t0 = time.time()
    p = subprocess.run(["nice", "-n", "10", cal, "diagnose", drive, "--json", out, "--no-progress", *extra],
                       capture_output=True, text=True)
    dt = time.time() - t0
    if p.returncode != 0:
        print(f"{drive}: diagnose failed: {p.stderr.strip()[-400:]}", file=sys.stderr)
        return None, dt
    open(tfile, "w").write(f"{dt}\n")
    return json.load(open(out)), dt


def truth_windows(drive):
    """What `effective_terms` and `effective_speed_growth` read: the
    wheels, the true circumferences, the vehicle file, and the truth's
    track and yaw at the wheels' times, with the step of 1 s windows; None
    without numpy."""
    try:
        import numpy as np
        import tomllib
    except ImportError:
        return None
    tr = np.genfromtxt(os.path.join(drive, "truth.csv"), delimiter=",", names=True)
    wh = np.genfromtxt(os.path.join(drive, "wheels.csv"), delimiter=",", names=True)
    truth = tomllib.load(open(os.path.join(drive, "truth.toml"), "rb"))
    veh = tomllib.load(open(os.path.join(drive, "vehicle.toml"), "rb"))
    tt = wh["t_s"]
    return {
        "np": np, "c": truth["circumference_m"], "veh": veh, "wh": wh, "tt": tt,
        "x": np.interp(tt, tr["t_s"], tr["x_m"]),
        "y": np.interp(tt, tr["t_s"], tr["y_m"]),
        "yaw": np.interp(tt, tr["t_s"], np.unwrap(tr["yaw_rad"])),
        "step": max(1, int(round(1.0 / np.median(np.diff(tt))))),
    }


def cached_in(name):
    """Make `f(truth_windows(drive))` a function of the drive folder,
    cached in DRIVE/NAME (None without numpy)."""
    def wrap(f):
        def of_drive(drive):
            cache = os.path.join(drive, name)
            if os.path.exists(cache):
                return json.load(open(cache))
            w = truth_windows(drive)
            if w is None:
                return None
            out = f(w)
            json.dump(out, open(cache, "w"))
            return out
        of_drive.__doc__ = f.__doc__
        return of_drive
    return wrap


@cached_in("effective.json")
def effective_terms(w):
    """The wheels' own load transfer and track against the truth: the
    wheels' heading error over 1 s windows, ((rr - rl) / t) - dpsi, with
    the true circumferences and the nominal track, regressed on dpsi (a
    track-like term), 2 v^2 dpsi / t (the load transfer's k_z), time and
    distance, with v and dpsi from the truth's track (moving windows only).
    make_drives' truth k_z is the tyres' radius part alone; the wheels also
    turn by the tyres' load-dependent slip. Cached in DRIVE/effective.json;
    None without numpy."""
    np, c, wh, tt, x, y, yaw, step = (w[k] for k in ("np", "c", "wh", "tt", "x", "y", "yaw", "step"))
    t, n = w["veh"]["track_width_m"], w["veh"]["ticks_per_rev"]
    i = np.arange(0, len(tt) - step, step)
    dl = (wh["rl_ticks"][i + step] - wh["rl_ticks"][i]) / n * c["rl"]
    dr = (wh["rr_ticks"][i + step] - wh["rr_ticks"][i]) / n * c["rr"]
    dpsi = yaw[i + step] - yaw[i]
    ds = np.hypot(x[i + step] - x[i], y[i + step] - y[i])
    dt = tt[i + step] - tt[i]
    v = ds / dt
    m = v > 2.0
    err = (dr - dl) / t - dpsi
    a = np.c_[dpsi, 2.0 * v * v * dpsi / t, dt, ds][m]
    b = np.linalg.lstsq(a, err[m], rcond=None)[0]
    return {"track_rel": float(-b[0]), "k_z": float(b[1])}


@cached_in("effective_kv.json")
def effective_speed_growth(w):
    """The wheels' own speed growth against the truth: on straights (1 s
    windows turning under 0.003 rad, above 3 m/s), the rear wheels' mean
    distance with the true circumferences less the truth's, regressed on
    ds (scale), v^2 ds (the catalogue's k_v, sign flipped: a growing
    radius makes the revolutions count short) and a_x ds (slip). The
    multibody tyres have a speed growth of their own (their rolling
    resistance and drive torque grow with speed), which make_drives does
    not record. Cached in DRIVE/effective_kv.json; None without numpy."""
    np, c, wh, tt, x, y, yaw, step = (w[k] for k in ("np", "c", "wh", "tt", "x", "y", "yaw", "step"))
    n = w["veh"]["ticks_per_rev"]
    i = np.arange(0, len(tt) - 2 * step, step)
    dl = (wh["rl_ticks"][i + step] - wh["rl_ticks"][i]) / n * c["rl"]
    dr = (wh["rr_ticks"][i + step] - wh["rr_ticks"][i]) / n * c["rr"]
    ds = np.hypot(x[i + step] - x[i], y[i + step] - y[i])
    ds_next = np.hypot(x[i + 2 * step] - x[i + step], y[i + 2 * step] - y[i + step])
    dt = tt[i + step] - tt[i]
    v = ds / dt
    ax = (ds_next - ds) / dt / dt
    m = (v > 3.0) & (np.abs(yaw[i + step] - yaw[i]) < 0.003)
    a = np.c_[ds, v * v * ds, ax * ds][m]
    b = np.linalg.lstsq(a, (0.5 * (dl + dr) - ds)[m], rcond=None)[0]
    return {"k_v": float(-b[1]), "windows": int(m.sum())}


def drive_key(drive):
    """What the tools read of `drive` (its sensor files and vehicle.toml),
    hashed: the suite's pairs whose second effect is the model's own tyre
    physics (latency + side-slip, antenna + side-slip, track + load
    transfer) are the drive of the first effect under another label, so
    a count over drives counts them twice; counts over distinct keys do
    not."""
    h = hashlib.md5()
    for f in ("gnss.csv", "wheels.csv", "imu.csv", "heading.csv", "vehicle.toml"):
        path = os.path.join(drive, f)
        if os.path.exists(path):
            h.update(open(path, "rb").read())
    return h.hexdigest()


def held_size(e, param, case, drive):
    """The size of effect `e` the drive's wheels hold, where the wheels add
    their own to the planted one: the track (the planted error of the
    nominal plus the tyres' own effective track, `effective_terms`, in the
    diagnosis's sign: 2W heading = true heading (1 + rel)) and the speed
    growth (`effective_speed_growth`); else the manifest's truth."""
    tv = case["effects"].get(e, {}).get(param)
    if e == "track_width" and tv is not None:
        eff = effective_terms(drive)
        return -eff["track_rel"] if eff else tv
    if e == "speed_radius_growth" and tv is not None:
        eff = effective_speed_growth(drive)
        return eff["k_v"] if eff else tv
    return tv


def normal_cdf(x):
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


def power_at(size, sigma, z_critical):
    """The chance that a two-sided Wald test at `z_critical` calls an
    effect of true `size` whose estimate has `sigma`: what the drive's
    information gives a test that decides on it, at the size it holds."""
    d = abs(size) / sigma
    return normal_cdf(d - z_critical) + normal_cdf(-d - z_critical)


def median(xs):
    xs = sorted(xs)
    return xs[len(xs) // 2] if xs else None


def fmt_x(v):
    return "-" if v is None else f"{v:.2f}x"


def limit_table(limits, null_limit):
    """The information limit (issue 37) per target effect, from the JSON's
    `information_limit`: the smallest size the drive shows (alone and with
    every other effect free) against the true size, the held-out test's
    detectable size where it reported one, and the joint Wald rule
    (|z| beyond the family's critical z) as a detector, with its estimate
    against the truth. Returns the table's lines and, per effect over
    distinct drives, (effect, drives, named, expected, spread) for
    `expected_svg`."""
    out = ["", "The information limit (`information_limit` of the JSON): medians over the drives, sizes as multiples of the true size.", "",
           "| effect | drives | limit alone | limit, every effect free | held-out test needs | joint Wald: found | expected from the drives' information (Fisher's sigma alone) | the product found | wrong names | estimate / truth | abs(estimate - truth) / sigma |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    totals = [0.0, 0.0, 0.0, 0, 0, 0]
    # (effect, drive key) -> [found by the joint Wald rule, named, power]:
    # each distinct drive once.
    distinct = {}
    for k, r in limits.items():
        e = k.split(" [")[0]
        for i, key in enumerate(r["key"]):
            distinct.setdefault((e, key), (r["found"][i], r["named"][i], r["drive_power"][i]))
        n = len(r["found"])
        ratio = median(r["ratio"])
        pull = median(r["pull"])
        pw = r["power"]
        expected = "-" if not pw else (f"{sum(pw):.1f} ± {math.sqrt(sum(q * (1 - q) for q in pw)):.1f}"
                                       + ("" if len(pw) == n else f" (of {len(pw)})")
                                       + f" ({sum(r['power_fisher']):.1f})")
        if pw:
            totals[0] += sum(pw)
            totals[1] += sum(q * (1 - q) for q in pw)
            totals[2] += sum(r["power_fisher"])
            totals[3] += sum(r["found"])
            totals[4] += sum(r["named"])
            totals[5] += len(pw)
        out.append(f"| {k} | {n} | {fmt_x(median(r['alone']))} | {fmt_x(median(r['joint']))} | "
                   f"{fmt_x(median(r['test']))} ({len(r['test'])}) | {sum(r['found'])}/{n} | {expected} | "
                   f"{sum(r['named'])}/{n} | {sum(r['wrong'])} | "
                   f"{'-' if ratio is None else f'{ratio:.2f}'} | {'-' if pull is None else f'{pull:.2f}'} |")
    fd = sum(bool(x) for x in null_limit)
    ids = defaultdict(int)
    for x in null_limit:
        for e in x:
            ids[e] += 1
    out.append(f"| all targets with a size | {totals[5]} | | | | {totals[3]}/{totals[5]} | "
               f"{totals[0]:.1f} ± {math.sqrt(totals[1]):.1f} ({totals[2]:.1f}) | {totals[4]}/{totals[5]} | | | |")
    by_effect = defaultdict(list)
    for (e, _), v in distinct.items():
        if v[2] is not None:
            by_effect[e].append(v)
    svg_rows = [(e, len(vs), sum(v[1] for v in vs), sum(v[2] for v in vs),
                 math.sqrt(sum(v[2] * (1 - v[2]) for v in vs))) for e, vs in by_effect.items()]
    sized = [v for v in distinct.values() if v[2] is not None]
    bare = [v for v in distinct.values() if v[2] is None]
    out.append(f"| distinct (effect, drive) targets with a size | {len(sized)} | | | | {sum(v[0] for v in sized)}/{len(sized)} | "
               f"{sum(v[2] for v in sized):.1f} ± {math.sqrt(sum(v[2] * (1 - v[2]) for v in sized)):.1f} | "
               f"{sum(v[1] for v in sized)}/{len(sized)} | | | |")
    if bare:
        out.append(f"| distinct targets without a size (the compass bias's three terms) | {len(bare)} | | | | "
                   f"{sum(v[0] for v in bare)}/{len(bare)} | - | {sum(v[1] for v in bare)}/{len(bare)} | | | |")
    out.append("")
    out.append("Expected from the drives' information: the sum over the drives of the power of the joint Wald test "
               "at the size each drive holds (the truth; for the track and the speed growth what the wheels show, "
               "the tyres' own added: `held_size`), |z| beyond the effect's critical z in Holm's order, with the "
               "joint sigma the decision uses (the larger of Fisher's under the refitted error model and the segments' "
               "scatter); ± the binomial spread; in brackets the same with Fisher's sigma alone. 'Distinct': a pair whose "
               "second effect is the model's own tyre physics is the first effect's drive under another label "
               "(`drive_key`): counted once. A row whose found count sits within that spread of the expected "
               "misses what its drives' information misses; one well below it loses what the data hold.")
    out.append("")
    out.append(f"joint Wald rule on null drives: {fd} of {len(null_limit)} with an effect beyond the critical z "
               f"(tyre physics aside): {dict(ids) or 'none'}")
    return out, svg_rows


def expected_svg(rows, path, title):
    """A dot plot of each row's named share of drives beside the share a
    test at the drives' own information names (its expectation and
    binomial spread), with the 90 % goal: `rows` of (label, drives,
    named, expected, spread)."""
    left, width, row_h, top = 330, 420, 22, 50
    h = top + row_h * len(rows) + 66
    x = lambda f: left + width * max(0.0, min(1.0, f))
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{left + width + 40}" height="{h}" '
           f'font-family="sans-serif" font-size="12">',
           f'<rect width="100%" height="100%" fill="white"/>',
           f'<text x="10" y="20" font-size="14" font-weight="bold">{title}</text>']
    for k in range(0, 11, 2):
        f = k / 10
        out.append(f'<line x1="{x(f)}" y1="{top - 8}" x2="{x(f)}" y2="{top + row_h * len(rows)}" stroke="#ddd"/>')
        out.append(f'<text x="{x(f)}" y="{top + row_h * len(rows) + 16}" text-anchor="middle">{k * 10} %</text>')
    out.append(f'<line x1="{x(0.9)}" y1="{top - 8}" x2="{x(0.9)}" y2="{top + row_h * len(rows)}" '
               f'stroke="#c00" stroke-dasharray="4 3"/>')
    out.append(f'<text x="{x(0.9)}" y="{top - 12}" text-anchor="middle" fill="#c00">goal 90 %</text>')
    for i, (label, n, named, exp, spread) in enumerate(rows):
        y = top + row_h * i + row_h / 2
        out.append(f'<text x="{left - 8}" y="{y + 4}" text-anchor="end">{label} ({n})</text>')
        out.append(f'<line x1="{x((exp - spread) / n)}" y1="{y}" x2="{x((exp + spread) / n)}" y2="{y}" '
                   f'stroke="#7aa6d8" stroke-width="8"/>')
        out.append(f'<line x1="{x(exp / n)}" y1="{y - 6}" x2="{x(exp / n)}" y2="{y + 6}" stroke="#1f4e8c" stroke-width="2"/>')
        out.append(f'<circle cx="{x(named / n)}" cy="{y}" r="5" fill="#222"/>')
    ly = top + row_h * len(rows) + 34
    out.append(f'<text x="{x(0.5)}" y="{ly}" text-anchor="middle">share of the row\'s drives named</text>')
    out.append(f'<circle cx="{left - 300}" cy="{ly + 16}" r="5" fill="#222"/>'
               f'<text x="{left - 290}" y="{ly + 20}">named by the product</text>')
    out.append(f'<line x1="{left - 130}" y1="{ly + 16}" x2="{left - 100}" y2="{ly + 16}" stroke="#7aa6d8" stroke-width="8"/>'
               f'<line x1="{left - 115}" y1="{ly + 10}" x2="{left - 115}" y2="{ly + 22}" stroke="#1f4e8c" stroke-width="2"/>'
               f'<text x="{left - 94}" y="{ly + 20}">what a test at the drives\' own information names: expected ± binomial spread</text>')
    out.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def effective_table(rows):
    """What the wheels show against the truth (`effective_terms`), per
    vehicle, beside the diagnosis's load transfer and track."""
    if not rows:
        return ["", "The wheels' effective terms: not measured (numpy missing)."]
    out = ["", "The wheels' effective terms against the truth (`effective_terms` in score.py): medians per vehicle; "
           "k_z against make_drives' radius part, the diagnosis's joint k_z (the information limit's fit, at the plain "
           "model's a_y) and the finding's k_z (where the load transfer was found; a_y read through it) against the "
           "effective one; the effective track on the drives without a planted track error.", "",
           "| vehicle | drives | effective k_z / radius k_z | joint k_z / effective | abs(joint - effective) / sigma | found | finding's k_z / effective | abs(finding - effective) / sigma | effective track (no track planted), range | track_width found there | the tyres' own k_v (no growth planted; `effective_speed_growth`), range |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for veh in sorted({r["vehicle"] for r in rows}):
        rs = [r for r in rows if r["vehicle"] == veh]
        ratio = median([r["k_z_eff"] / r["k_z_radius"] for r in rs if r["k_z_radius"]])
        est = median([r["k_z_est"] / r["k_z_eff"] for r in rs if r["k_z_est"] is not None and r["k_z_eff"]])
        pull = median([abs(r["k_z_est"] - r["k_z_eff"]) / r["k_z_sigma"]
                       for r in rs if r["k_z_est"] is not None and r["k_z_sigma"]])
        fr = [r for r in rs if r["k_z_found"] is not None and r["k_z_eff"]]
        f_est = median([r["k_z_found"] / r["k_z_eff"] for r in fr])
        f_pull = median([abs(r["k_z_found"] - r["k_z_eff"]) / r["k_z_found_sigma"] for r in fr if r["k_z_found_sigma"]])
        tr = [r["track_eff"] for r in rs if not r["planted_track"]]
        found = sum(r["track_found"] for r in rs if not r["planted_track"])
        kv = [r["k_v_eff"] for r in rs if not r["planted_k_v"] and r["k_v_eff"] is not None]
        kv_range = f"{min(kv):.1e} to {max(kv):.1e}" if kv else "-"
        out.append(f"| {veh} | {len(rs)} | {'-' if ratio is None else f'{ratio:.2f}'} | "
                   f"{'-' if est is None else f'{est:.2f}'} | {'-' if pull is None else f'{pull:.1f}'} | "
                   f"{len(fr)} | {'-' if f_est is None else f'{f_est:.2f}'} | {'-' if f_pull is None else f'{f_pull:.1f}'} | "
                   f"{100 * min(tr):+.2f} to {100 * max(tr):+.2f} % | {found} of {len(tr)} | {kv_range} |")
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out_dir")
    ap.add_argument("--calibrator", default=os.path.normpath(DEFAULT_CAL))
    ap.add_argument("--rerun", action="store_true")
    ap.add_argument("--held-out-only", action="store_true",
                    help="only the held-out test decides (diagnosis-held-out.json): the figures before Holm's Wald decision")
    a = ap.parse_args()
    manifest = json.load(open(os.path.join(a.out_dir, "manifest.json")))
    rows = OrderedDict()
    null_n = null_false = 0
    null_found = defaultdict(int)
    inherent_found = defaultdict(int)
    times = []
    lines = []
    limits = OrderedDict()
    null_limit = []
    effective = []
    per_vehicle = defaultdict(list)
    for case in manifest:
        drive = os.path.join(a.out_dir, case["drive"])
        d, dt = run(a.calibrator, drive, a.rerun,
                    ("--held-out-only",) if a.held_out_only else (),
                    "-held-out" if a.held_out_only else "")
        if d is None:
            continue
        times.append(dt)
        found = [f["effect"] for f in d.get("findings", [])]
        amb = [e for x in d.get("ambiguous", []) for e in x.get("effects", [])]
        truth, allowed = case["truth"], allowed_on(case, drive)
        extra = [e for e in found if e not in truth and e not in allowed]
        for e in found:
            if e in allowed:
                inherent_found[e] += 1
        fit = d.get("fit", {})
        before = fit.get("before", {}).get("holdout_position_rmse_m")
        after = fit.get("after", {}).get("holdout_position_rmse_m")
        msg = (f"{case['drive']:<44} {case['vehicle']:<12} found [{', '.join(found)}] "
               f"ambiguous [{', '.join(amb)}] pos RMSE {before:.3f} -> {after:.3f} m, {dt:.1f} s")
        print(msg, flush=True)
        lines.append(msg)
        per_vehicle[case["vehicle"]].append((before, after))
        lim = d.get("information_limit")
        if lim and not truth:
            # The joint Wald rule on a null drive: effects beyond the
            # family's critical z other than the model's own tyre physics.
            null_limit.append([x["effect"] for x in lim["effects"]
                               if x["effect"] not in allowed
                               and abs(x.get("joint", {}).get("wald_z", 0.0)) >= lim["z_critical"]])
        if lim:
            drive_id = drive_key(drive)
            by_id = {x["effect"]: x for x in lim["effects"]}
            beyond = [e for e, x in by_id.items()
                      if abs(x.get("joint", {}).get("wald_z", 0.0)) >= lim["z_critical"]]
            for e in truth:
                x = by_id.get(e)
                if x is None:
                    continue
                key = e if len(truth) == 1 else f"{e} [{case['label']}]"
                r = limits.setdefault(key, defaultdict(list))
                tv = case["effects"].get(e, {}).get(x["parameter"])
                j = x.get("joint", {})
                r["found"].append(e in beyond)
                r["named"].append(e in found)
                r["key"].append(drive_id)
                r["drive_power"].append(None)
                r["wrong"].append(any(b not in truth and b not in allowed for b in beyond))
                if tv:
                    if x.get("smallest") is not None:
                        r["alone"].append(x["smallest"] / abs(tv))
                    if j.get("smallest") is not None:
                        r["joint"].append(j["smallest"] / abs(tv))
                    zc = next((w["z_critical"] for w in d.get("wald", []) if w["effect"] == e), lim["z_critical"])
                    hv = held_size(e, x["parameter"], case, drive)
                    if j.get("sigma"):
                        r["power"].append(power_at(hv, j["sigma"], zc))
                        r["drive_power"][-1] = r["power"][-1]
                    if j.get("sigma_fisher"):
                        r["power_fisher"].append(power_at(hv, j["sigma_fisher"], zc))
                    if j.get("estimate") is not None and j.get("sigma"):
                        r["ratio"].append(j["estimate"] / tv)
                        r["pull"].append(abs(j["estimate"] - tv) / j["sigma"])
                na = [n for n in d.get("not_accepted", []) if n["effect"] == e]
                if tv and na and na[0].get("detectable") and na[0]["detectable"].get("smallest") is not None:
                    r["test"].append(na[0]["detectable"]["smallest"] / abs(tv))
        eff = effective_terms(drive)
        if eff is not None:
            lt = next((x for x in (lim or {}).get("effects", [])
                       if x["effect"] == "load_transfer_radius"), {}).get("joint", {})
            lt_found = next((f for f in d.get("findings", []) if f["effect"] == "load_transfer_radius"), {})
            effective.append({
                "vehicle": case["vehicle"],
                "planted_track": case["effects"].get("track_width", {}).get("rel"),
                "k_z_eff": eff["k_z"], "track_eff": eff["track_rel"],
                "k_z_radius": case["effects"].get("load_transfer_radius", {}).get("k_z"),
                "k_z_est": lt.get("estimate"), "k_z_sigma": lt.get("sigma"),
                "k_z_found": lt_found.get("parameters", {}).get("k_z"),
                "k_z_found_sigma": lt_found.get("sigmas", {}).get("k_z"),
                "track_found": "track_width" in found,
                "k_v_eff": (effective_speed_growth(drive) or {}).get("k_v"),
                "planted_k_v": case["effects"].get("speed_radius_growth", {}).get("k_v"),
            })
        if not truth:
            null_n += 1
            null_false += bool(extra)
            for e in found:
                null_found[e] += 1
            continue
        for e in truth:
            key = e if len(truth) == 1 else f"{e} [{case['label']}]"
            r = rows.setdefault(key, defaultdict(list))
            r["drives"].append(1)
            r["detected"].append(e in found)
            r["attributed"].append(e in found and not extra)
            r["wrong"].append(bool(extra))
            r["ambiguous"].append(e in amb)
            r["before"].append(before)
            r["after"].append(after)
            r["others"].extend(x for x in found if x not in truth)
            na = [n for n in d.get("not_accepted", []) if n["effect"] == e]
            if e not in found and na and na[0].get("detectable") and na[0]["detectable"].get("smallest") is not None:
                det = na[0]["detectable"]
                tv = case["effects"].get(e, {}).get(det["parameter"])
                if tv:
                    r["needed"].append(det["smallest"] / tv)
    out = ["", "| effect | drives | detected | attributed | wrong names | ambiguous | held-out pos. RMSE before -> after (mean) | other ids found | undetected: detectable size (median, x true) |",
           "|---|---|---|---|---|---|---|---|---|"]
    for k, r in rows.items():
        n = len(r["drives"])
        mb = sum(r["before"]) / n
        ma = sum(r["after"]) / n
        oth = defaultdict(int)
        for x in r["others"]:
            oth[x] += 1
        nd = sorted(r["needed"])
        need = f"{nd[len(nd) // 2]:.1f}x ({len(nd)})" if nd else ""
        out.append(f"| {k} | {n} | {sum(r['detected'])}/{n} | {sum(r['attributed'])}/{n} | {sum(r['wrong'])} | "
                   f"{sum(r['ambiguous'])} | {mb:.3f} -> {ma:.3f} m ({100 * (ma / mb - 1):+.0f} %) | "
                   f"{', '.join(f'{x} x{c}' for x, c in sorted(oth.items()))} | {need} |")
    table, svg_rows = limit_table(limits, null_limit)
    out.extend(table)
    if svg_rows:
        expected_svg(svg_rows, os.path.join(a.out_dir, "expected.svg"),
                     "Multibody drives: named against the drives' information (distinct drives per effect)")
    out.extend(effective_table(effective))
    out.extend(["", "Held-out position RMSE per vehicle (`fit.before` / `fit.after` of the JSON), mean over its drives:", "",
                "| vehicle | drives | plain model | with the findings |", "|---|---|---|---|"])
    for v, xs in sorted(per_vehicle.items()):
        ok = [(b, a) for b, a in xs if b is not None and a is not None]
        if ok:
            out.append(f"| {v} | {len(ok)} | {sum(b for b, _ in ok) / len(ok):.2f} m | "
                       f"{sum(a for _, a in ok) / len(ok):.2f} m |")
    out.append("")
    out.append(f"null drives: {null_n}, with a false discovery (beyond the model's own tyre physics): {null_false}; "
               f"ids found on null drives: {dict(null_found) or 'none'}")
    out.append(f"tyre physics found on any drive (allowed): {dict(inherent_found) or 'none'} of {len(times)} drives")
    if times:
        out.append(f"diagnosis time: {sum(times) / len(times):.2f} s per drive on average (max {max(times):.2f} s), {sum(times):.0f} s in all")
    print("\n".join(out))
    with open(os.path.join(a.out_dir, "score.md"), "w") as f:
        f.write("\n".join(lines + out) + "\n")


if __name__ == "__main__":
    main()
