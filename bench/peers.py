#!/usr/bin/env python3
"""Benchmark of `swg-host fit` against the peers a user would otherwise pick.

Peers, each fitting the same model with a plain, unweighted residual sum of squares:
  * scipy.optimize.least_squares, multi-start (20 starts, trf, analytic Jacobian),
  * scipy.optimize.differential_evolution (scipy's defaults, capped generations),
  * pyswarms GlobalBestPSO (the options of pyswarms' own examples, capped iterations).

The model (model-core/src/lib.rs, host/src/fit.rs):
  T = c1·θ + c2·θ³ + c3·θ⁵ + h·|cos φ|·(e^(−rφ) + r·sin φ − cos φ)
  x = clamp(θ/A, −1, 1), φ = asin x while θ rises, π − asin x while θ falls.
Loop table: A = max|θ|, direction from the branch. Recording: direction and A per sample
from a port of host/src/segment.rs (zigzag turning points, noise band, parabola vertex);
the table reports how far the port's RSS is from swg-host's on the same parameters.

The peers search five identifiable parameters in a scaled space, S = largest amplitude:
  a1 = c1·S, a3 = c2·S³, a5 = c3·S⁵   (N·m at full deflection)
  w                                   (N·m: the hysteresis torque at θ = 0 while falling
                                       on a loop of amplitude S, i.e. the loop's half width)
  r = β/ω
  hysteresis term = w·(A/S)·|cos φ|·(e^(−rφ) + r·sin φ − cos φ)/(1 + e^(−rπ))
Every peer's best point is written as a canonical parameter file (ω = 1, β = r,
α = k·(1 + r²), k = w/(S·(1 + e^(−rπ)))) and evaluated by `swg-host fit --compare`, so
every RSS in the table comes from the same code, the same direction and amplitude.

Timing: single-threaded (OPENBLAS_NUM_THREADS=1 unless set), like swg-host. The peers'
times are in-process (time.perf_counter) and cover reading the file, preparing direction and
amplitude, and the whole optimisation; Python start-up and imports are excluded. swg-host's
times are the wall time of the whole `swg-host fit FILE --json` process, started from Python.
"""
import os

# One thread, like swg-host: on a busy 2-core machine OpenBLAS' threads make the peers'
# linear algebra (least_squares' SVDs) several times slower, not faster.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import json
import logging
import math
import resource
import statistics
import subprocess
import sys
import time

import numpy as np
import scipy
import scipy.optimize as so
import pyswarms as ps

logging.disable(logging.CRITICAL)  # pyswarms logs every run at INFO

RISING, FALLING = 1, -1
BRANCH_DIRECTION = {
    "forward_loading": RISING,
    "reverse_unloading": RISING,
    "forward_unloading": FALLING,
    "reverse_loading": FALLING,
}

# ---------------------------------------------------------------- input


def read_input(path):
    """Returns (theta, torque, direction, amplitude) as numpy arrays."""
    meta, header, rows = {}, None, []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            if line.startswith("#"):
                if header is None and ":" in line:
                    key, value = line[1:].split(":", 1)
                    meta[key.strip()] = value.strip()
                continue
            if header is None:
                header = [c.strip() for c in line.split(",")]
            else:
                rows.append(line.split(","))
    col = {name: i for i, name in enumerate(header)}
    if "branch" in col:
        theta = np.array([float(r[col["deflection_rad"]]) for r in rows])
        torque = np.array([float(r[col["torque_nm"]]) for r in rows])
        direction = np.array([BRANCH_DIRECTION[r[col["branch"]].strip()] for r in rows])
        amplitude = np.full(len(theta), np.max(np.abs(theta)))
        return theta, torque, direction, amplitude
    data = np.array([[float(v) for v in r] for r in rows])
    torque = data[:, col["torque_nm"]]
    time_s = data[:, col["time_s"]]
    if "deflection_rad" in col:
        theta = data[:, col["deflection_rad"]]
    else:
        ratio = float(meta["ratio"])
        theta = data[:, col["theta_in_rad"]] / ratio - data[:, col["theta_out_rad"]]
    direction, amplitude = segment(time_s, theta)
    return theta, torque, direction, amplitude


# ------------------------------------------- port of host/src/segment.rs


def noise_from_second_differences(x):
    d2 = x[2:] - 2.0 * x[1:-1] + x[:-2]
    return math.sqrt(np.mean(d2 * d2) / 6.0) if len(d2) else 0.0


def typical_step(x):
    steps = np.abs(np.diff(x))
    steps = steps[steps > 0.0]
    if len(steps) == 0:
        return 0.0
    return float(np.partition(steps, len(steps) // 2)[len(steps) // 2])


def zigzag(x, band):
    extremes = []
    max_i = min_i = 0
    rising = None
    for i, v in enumerate(x.tolist()):
        if v > x[max_i]:
            max_i = i
        if v < x[min_i]:
            min_i = i
        if rising is None:
            if v - x[min_i] > band:
                rising, max_i = True, i
            elif x[max_i] - v > band:
                rising, min_i = False, i
        elif rising:
            if x[max_i] - v > band:
                extremes.append((max_i, True))
                rising, min_i = False, i
        else:
            if v - x[min_i] > band:
                extremes.append((min_i, False))
                rising, max_i = True, i
    return extremes


def fit_vertex(t, x, is_maximum):
    """(time, value) of the vertex of the least-squares parabola, if it is a cap (maximum)
    or a cup (minimum) with its vertex inside the window; else None. The quartic term of a
    sinusoidal reversal, d = c²/(6a) clamped to |c|/2, is subtracted and the parabola
    refitted (three passes)."""
    if len(x) < 5:
        return None
    t0, t1 = t[0], t[-1]
    span = max(t1 - t0, sys.float_info.min)
    tau = 2.0 * (t - t0) / span - 1.0
    v = np.vander(tau, 3, increasing=True)
    normal = v.T @ v
    quartic, vertex = 0.0, None
    for _ in range(3):
        center = 0.0 if vertex is None else vertex[0]
        y = x - quartic * (tau - center) ** 4
        try:
            a, b, c = np.linalg.solve(normal, v.T @ y)
        except np.linalg.LinAlgError:
            return None
        if not (np.isfinite(a) and np.isfinite(b) and np.isfinite(c)) or c == 0.0:
            return None
        cap = c < 0.0 if is_maximum else c > 0.0
        vertex_tau = -b / (2.0 * c)
        if not (cap and -1.0 <= vertex_tau <= 1.0):
            return None
        value = a - b * b / (4.0 * c)
        vertex = (vertex_tau, value)
        quartic = min(max(c * c / (6.0 * value), -abs(c) / 2.0), abs(c) / 2.0) if value != 0.0 else 0.0
    return t0 + (vertex[0] + 1.0) * span / 2.0, vertex[1]


def refine_extreme(t, x, index, previous, nxt, is_maximum, noise):
    """Parabola vertex over ±15 % of the mean distance to the neighbouring turning points,
    re-centred once, kept within the expected overshoot of the noisy extreme."""
    peak = x[index]
    reach = max((nxt - previous) * 15 // 200, 2)
    center = index
    estimate = None
    for _ in range(2):
        first = max(center - reach, 0, previous)
        last = min(center + reach, nxt)
        found = fit_vertex(t[first:last + 1], x[first:last + 1], is_maximum)
        if found is None:
            break
        vertex_time, vertex = found
        estimate = (vertex, last - first + 1)
        center = first + min(int(np.searchsorted(t[first:last + 1], vertex_time, side="left")), last - first)
    if estimate is None:
        return peak
    vertex, count = estimate
    overshoot = noise * (math.sqrt(2.0 * math.log(count)) + 1.0)
    if is_maximum:
        return min(max(vertex, peak - overshoot), peak)
    return min(max(vertex, peak), peak + overshoot)


def segment(t, x):
    n = len(x)
    step = typical_step(x)
    noise = max(noise_from_second_differences(x), step / math.sqrt(12.0))
    band = max(10.0 * noise, 2.0 * step, 1e-9 * (x.max() - x.min()))
    extremes = zigzag(x, band)
    if not extremes:
        raise SystemExit("the deflection never reverses")
    tps = []
    for k, (index, is_max) in enumerate(extremes):
        previous = extremes[k - 1][0] if k > 0 else 0
        nxt = extremes[k + 1][0] if k + 1 < len(extremes) else n - 1
        tps.append((index, is_max, refine_extreme(t, x, index, previous, nxt, is_max, noise)))
    # Legs run from one turning point to the next; the partial legs at the ends are bounded
    # by the first and last samples. A leg's amplitude is the larger magnitude of its ends.
    direction = np.empty(n, dtype=int)
    amplitude = np.empty(n)
    begin = 0
    for leg in range(len(tps) + 1):
        start = abs(tps[leg - 1][2]) if leg > 0 else abs(x[0])
        if leg < len(tps):
            index, is_max, value = tps[leg]
            end, end_index, leg_direction = abs(value), index + 1, (RISING if is_max else FALLING)
        else:
            end, end_index, leg_direction = abs(x[-1]), n, (FALLING if tps[-1][1] else RISING)
        direction[begin:end_index] = leg_direction
        amplitude[begin:end_index] = max(start, end)
        begin = end_index
    amplitude = np.maximum(amplitude, max(band, sys.float_info.min))
    return direction, amplitude


# ---------------------------------------------------------------- model


class Problem:
    """The model in the scaled parameters q = (a1, a3, a5, w, r), plain RSS, and a record
    of the best objective value over time."""

    R_BOUND = 10.0

    def __init__(self, theta, torque, direction, amplitude, t0):
        self.torque = torque
        self.scale = float(np.max(amplitude))
        u = theta / self.scale
        self.poly = np.stack([u, u**3, u**5])  # 3 × n
        x = np.clip(theta / amplitude, -1.0, 1.0)
        abs_cos = np.sqrt((1.0 - x) * (1.0 + x))
        asin = np.arcsin(x)
        self.phase = np.where(direction == RISING, asin, math.pi - asin)
        self.sin = x
        self.cos = np.where(direction == RISING, abs_cos, -abs_cos)
        self.g = amplitude / self.scale * abs_cos
        tmax = float(np.max(np.abs(torque)))
        bound = np.array([10 * tmax] * 4 + [self.R_BOUND])
        self.lower, self.upper = -bound, bound
        self.t0 = t0
        self.trace = []  # (seconds since t0, best objective so far, its q)
        self.best = math.inf
        self.best_q = None
        self.evaluations = 0

    def _record(self, value, q):
        self.evaluations += 1
        if value < self.best:
            self.best = value
            self.best_q = np.array(q, dtype=float)
            self.trace.append((time.perf_counter() - self.t0, value, self.best_q))

    def predict(self, q):
        a1, a3, a5, w, r = q
        sigma = 1.0 / (1.0 + math.exp(-r * math.pi))  # e^(−L), L = ln(1 + e^(−rπ))
        log_l = -math.log(sigma)
        e = np.exp(-r * self.phase - log_l)
        hyst = e + (r * self.sin - self.cos) * sigma
        return a1 * self.poly[0] + a3 * self.poly[1] + a5 * self.poly[2] + w * self.g * hyst

    def residuals(self, q):
        res = self.torque - self.predict(q)
        self._record(float(res @ res), q)
        return res

    def jacobian(self, q):
        a1, a3, a5, w, r = q
        sigma = 1.0 / (1.0 + math.exp(-r * math.pi))
        e = np.exp(-r * self.phase + math.log(sigma))
        lin = r * self.sin - self.cos
        hyst = e + lin * sigma
        d_r = e * (math.pi * (1.0 - sigma) - self.phase) + self.sin * sigma + lin * sigma * (1.0 - sigma) * math.pi
        return -np.stack([self.poly[0], self.poly[1], self.poly[2], self.g * hyst, w * self.g * d_r], axis=1)

    def rss(self, q):
        res = self.torque - self.predict(q)
        value = float(res @ res)
        self._record(value, q)
        return value

    def rss_swarm(self, qs):
        """RSS of every particle (rows of qs)."""
        a1, a3, a5, w, r = (qs[:, i:i + 1] for i in range(5))
        sigma = 1.0 / (1.0 + np.exp(-r * math.pi))
        e = np.exp(-r * self.phase[None, :] + np.log(sigma))
        hyst = e + (r * self.sin[None, :] - self.cos[None, :]) * sigma
        pred = a1 * self.poly[0] + a3 * self.poly[1] + a5 * self.poly[2] + w * self.g * hyst
        res = self.torque[None, :] - pred
        values = np.einsum("ij,ij->i", res, res)
        values = np.where(np.isfinite(values), values, np.inf)
        i = int(np.argmin(values))
        self.evaluations += len(values) - 1
        self._record(float(values[i]), qs[i])
        return values

    def canonical(self, q):
        """(c1, c2, c3, alpha, beta, omega) with ω = 1, β = r, α = k·(1 + r²)."""
        a1, a3, a5, w, r = (float(v) for v in q)
        s = self.scale
        k = w / (s * (1.0 + math.exp(-r * math.pi)))
        return {"c1": a1 / s, "c2": a3 / s**3, "c3": a5 / s**5, "alpha": k * (1.0 + r * r), "beta": r, "omega": 1.0}


# ---------------------------------------------------------------- peers


def prepare(path):
    t0 = time.perf_counter()
    return Problem(*read_input(path), t0)


def run_least_squares(path, seed, starts=20):
    p = prepare(path)
    rng = np.random.default_rng(seed)
    for _ in range(starts):
        x0 = rng.uniform(p.lower, p.upper)
        so.least_squares(p.residuals, x0, jac=p.jacobian, bounds=(p.lower, p.upper), method="trf",
                         x_scale="jac", loss="linear")
    return p


def run_differential_evolution(path, seed, maxiter):
    p = prepare(path)
    so.differential_evolution(p.rss, list(zip(p.lower, p.upper)), seed=seed, maxiter=maxiter)
    return p


def run_pyswarms(path, seed, iters, particles=50):
    p = prepare(path)
    np.random.seed(seed)  # pyswarms draws from numpy's global generator
    optimizer = ps.single.GlobalBestPSO(n_particles=particles, dimensions=5,
                                        options={"c1": 0.5, "c2": 0.3, "w": 0.9},
                                        bounds=(p.lower, p.upper))
    optimizer.optimize(p.rss_swarm, iters=iters, verbose=False)
    return p


# ---------------------------------------------------------------- driver


def loop_torque(params, amplitude, points=2001):
    """The model's torque over one clean loop θ = A·sin φ, φ from −π/2 to 3π/2."""
    phi = np.linspace(-math.pi / 2, 3 * math.pi / 2, points)
    theta = amplitude * np.sin(phi)
    r = params["beta"] / params["omega"]
    h = amplitude * params["alpha"] / (params["omega"] * (1.0 + r * r))
    z = h * np.abs(np.cos(phi)) * (np.exp(-r * phi) + r * np.sin(phi) - np.cos(phi))
    return params["c1"] * theta + params["c2"] * theta**3 + params["c3"] * theta**5 + z


def distance_from_truth(params, truth, amplitude):
    """RMS of the fitted minus the true torque over one clean loop of the simulated amplitude, N·m."""
    d = loop_torque(params, amplitude) - loop_torque(truth, amplitude)
    return float(np.sqrt(np.mean(d * d)))


def recording_metadata(path):
    """The `# key: value` lines of a recording, or None for a loop table."""
    with open(path) as f:
        first = f.readline().strip()
        if first != "# swg-recording v1":
            return None
        meta = {}
        for line in f:
            if not line.startswith("#"):
                break
            if ":" in line:
                key, value = line[1:].split(":", 1)
                meta[key.strip()] = value.strip()
        return meta


def children_cpu():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def swg_json(swg, args):
    # The peers fit the symmetric-loop rule on each leg: so does `--model genetic-loop`.
    out = subprocess.run([swg, "fit", *args, "--model", "genetic-loop", "--json"], check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def fmt_time(t):
    if t is None:
        return "never"
    return f"{t * 1e3:.1f} ms" if t < 1.0 else f"{t:.2f} s"


def fmt_ratio(t, ours):
    return "—" if t is None else f"{t / ours:,.0f}×"


def first_within(swg, path, outdir, rec, threshold, chunk=100, most=2000):
    """When a run's best point first had an RSS within `threshold`, by swg-host's evaluation.

    The candidates are the run's successive best points whose own RSS is near the threshold,
    in time order; swg-host evaluates them in chunks until one is within it. So a Python port
    of the direction and amplitude that lags behind swg-host's cannot distort the time."""
    candidates = [(t, q) for t, v, q in rec["trace"] if v <= 1.1 * threshold][:most]
    for start in range(0, len(candidates), chunk):
        part = candidates[start:start + chunk]
        args = [path]
        for k, (_, q) in enumerate(part):
            os.makedirs(os.path.join(outdir, "candidates"), exist_ok=True)
            file = os.path.join(outdir, "candidates", f"{k}.json")
            with open(file, "w") as f:
                json.dump({"model": "genetic-hysteresis", "params": rec["canonical"](q)}, f)
            args += ["--compare", file]
        for (t, _), c in zip(part, swg_json(swg, args)["compared"]):
            if c["rss"] <= threshold:
                return t
    return None


def median_time(times):
    """Median of run times where math.inf stands for 'never'; None when the median is never."""
    m = statistics.median(times)
    return None if math.isinf(m) else m


def bench_file(path, swg, outdir, runs, ours_runs, caps, truth_file):
    name = os.path.splitext(os.path.basename(path))[0]
    meta = recording_metadata(path)
    truth_file = truth_file if meta is not None else None
    print(f"\n== {path}", flush=True)

    # swg-host: one untimed run (file cache), then `ours_runs` timed runs with seeds 1….
    swg_json(swg, [path])
    ours = []
    for seed in range(1, ours_runs + 1):
        cpu = children_cpu()
        t = time.perf_counter()
        report = swg_json(swg, [path, "--seed", str(seed)])
        ours.append({"seed": seed, "total": time.perf_counter() - t, "cpu": children_cpu() - cpu,
                     "rss": report["rss"], "params": report["params"]})
    n = report["n"]
    ours_time = statistics.median(r["total"] for r in ours)
    print(f"swg-host fit: {ours_runs} runs, median {fmt_time(ours_time)}, "
          f"rss {min(r['rss'] for r in ours):.9g} … {max(r['rss'] for r in ours):.9g}", flush=True)

    peers = {
        "scipy least_squares ×20 starts": lambda s: run_least_squares(path, s),
        "scipy differential_evolution": lambda s: run_differential_evolution(path, s, caps["de_maxiter"]),
        "pyswarms GlobalBestPSO": lambda s: run_pyswarms(path, s, caps["pso_iters"]),
    }
    results = {}
    for label, run in peers.items():
        records = []
        for seed in range(runs):
            cpu = time.process_time()
            t = time.perf_counter()
            problem = run(seed)
            total = time.perf_counter() - t
            records.append({"seed": seed, "total": total, "cpu": time.process_time() - cpu,
                            "trace": problem.trace, "own_rss": problem.best,
                            "params": problem.canonical(problem.best_q), "evaluations": problem.evaluations,
                            "canonical": problem.canonical})
            print(f"{label}: seed {seed}: {fmt_time(total)}, own rss {problem.best:.9g}, "
                  f"{problem.evaluations} evaluations", flush=True)
        results[label] = records

    # Every peer's best point, evaluated by swg-host on its own direction and amplitude.
    compare_args = [path]
    for label, records in results.items():
        for rec in records:
            rec["file"] = os.path.join(outdir, f"{name}-{label.split()[1]}-seed{rec['seed']}.json")
            with open(rec["file"], "w") as f:
                json.dump({"model": "genetic-hysteresis", "params": rec["params"]}, f, indent=1)
            compare_args += ["--compare", rec["file"]]
    if truth_file:
        compare_args += ["--compare", truth_file]
    compared = swg_json(swg, compare_args)["compared"]
    everything = [rec for records in results.values() for rec in records]
    for rec, c in zip(everything, compared):
        rec["rss"] = c["rss"]
    truth_rss = compared[-1]["rss"] if truth_file else None

    best = min(r["rss"] for r in ours + everything)
    threshold = 1.01 * best
    mismatch = max(abs(rec["rss"] - rec["own_rss"]) / rec["rss"] for rec in everything)

    truth = None
    if truth_file:
        with open(truth_file) as f:
            truth = json.load(f)["params"]
        amplitude = float(meta["amplitude_rad"])

    def distance(records):
        if truth is None:
            return ""
        best_run = min(records, key=lambda r: r["rss"])
        return f" {distance_from_truth(best_run['params'], truth, amplitude):.4f} |"

    ours_rss = [r["rss"] for r in ours]
    ours_t1 = ours_time if max(ours_rss) <= threshold else None
    rows = [("**swg-host fit** (whole process)", len(ours), min(ours_rss), max(ours_rss), ours_time, "1×",
             ours_t1, "1×" if ours_t1 is not None else "—", distance(ours))]
    for label, records in results.items():
        t1s = []
        for rec in records:
            hit = first_within(swg, path, outdir, rec, threshold)
            t1s.append(math.inf if hit is None else hit)
        total = statistics.median(rec["total"] for rec in records)
        t1 = median_time(t1s)
        reached = sum(1 for t in t1s if not math.isinf(t))
        rss = [rec["rss"] for rec in records]
        rows.append((label, len(records), min(rss), max(rss), total, fmt_ratio(total, ours_time),
                     t1, fmt_ratio(t1, ours_time) + f" ({reached}/{len(records)} runs reach it)", distance(records)))

    truth_header = " RMS from the true loop, N·m |" if truth else ""
    lines = [
        f"### {os.path.basename(path)} ({n} samples)",
        "",
        f"Best RSS over every run of every method: {best:.9g} (N·m)²; \"within 1 %\" means RSS ≤ {threshold:.9g}.",
        "",
        "| method | runs | best RSS | worst run's RSS | median total time | total / ours | median time to 1 % "
        "| to 1 % / ours |" + truth_header,
        "|---|---|---|---|---|---|---|---|" + ("---|" if truth else ""),
    ]
    for label, count, rbest, rworst, total, ratio, t1, ratio1, dist in rows:
        lines.append(f"| {label} | {count} | {rbest:.9g} | {rworst:.9g} | {fmt_time(total)} | {ratio} | "
                     f"{fmt_time(t1)} | {ratio1} |{dist}")
    lines.append("")
    if truth_file:
        lines.append(f"RSS at the true parameters the recording was simulated from ({truth_file}): "
                     f"{truth_rss:.9g} (N·m)². \"RMS from the true loop\": the best run's torque minus the true "
                     f"torque over one clean loop θ = A·sin φ, A = {amplitude} rad.")
    cpu = [("swg-host", statistics.median(r["cpu"] for r in ours))]
    cpu += [(label.split()[1], statistics.median(rec["cpu"] for rec in records)) for label, records in results.items()]
    lines.append("Median CPU time (user + system; less sensitive to other load than the wall times above): "
                 + ", ".join(f"{name} {fmt_time(t)}" for name, t in cpu) + ".")
    lines.append(f"Largest relative difference between a peer's own RSS (Python port of the direction and "
                 f"amplitude) and swg-host's evaluation of its parameters: {mismatch:.1e}.")
    fastest = min(rows[1:], key=lambda r: r[4])
    reaching = [r for r in rows[1:] if r[6] is not None]
    fastest_reaching = min(reaching, key=lambda r: r[4]) if reaching else None
    peer_t1 = [r[6] for r in reaching]
    best_peer = min(r[2] for r in rows[1:])
    goal = [
        f"whole swg-host run ≥ 50× faster than the fastest peer's total: "
        f"{'yes' if fastest[4] >= 50 * ours_time else 'no'} ({fastest[4] / ours_time:,.0f}×, {fastest[0]}"
        + ("" if fastest_reaching is None or fastest_reaching is fastest else
           f"; {fastest_reaching[4] / ours_time:,.0f}× against the fastest that reaches 1 %, {fastest_reaching[0]}")
        + ")",
        "faster than every peer's time to 1 %: "
        + ("no: swg-host's RSS is not within 1 % of the best" if ours_t1 is None else
           ("yes" if all(t > ours_t1 for t in peer_t1) else "no")),
        f"RSS equal or better than every peer's: {'yes' if max(ours_rss) <= best_peer else 'no'} "
        f"(swg-host {max(ours_rss):.9g}, best peer {best_peer:.9g}, "
        f"{(max(ours_rss) / best_peer - 1) * 100:+.3f} %)",
    ]
    lines += ["", "Goal: " + "; ".join(goal) + ".", ""]
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="+", help="loop tables and recordings")
    ap.add_argument("--swg-host", required=True, help="the swg-host binary")
    ap.add_argument("--out", required=True, help="directory for the peers' parameter files and results.md")
    ap.add_argument("--runs", type=int, default=3, help="runs of every peer")
    ap.add_argument("--ours-runs", type=int, default=7, help="timed runs of swg-host fit")
    ap.add_argument("--de-maxiter", type=int, default=300, help="cap on differential_evolution's generations")
    ap.add_argument("--pso-iters", type=int, default=1000, help="pyswarms iterations")
    ap.add_argument("--truth", help="parameter file the recordings were simulated from (reported, not a method)")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    caps = {"de_maxiter": args.de_maxiter, "pso_iters": args.pso_iters}
    sections = [bench_file(path, args.swg_host, args.out, args.runs, args.ours_runs, caps, args.truth)
                for path in args.files]
    header = [
        "## `swg-host fit` against the peers",
        "",
        f"Machine: {os.cpu_count()} CPUs, load average at the end {os.getloadavg()[0]:.2f}; Python "
        f"{sys.version.split()[0]}, numpy {np.__version__}, scipy {scipy.__version__}, pyswarms {ps.__version__}.",
        "",
        f"- Peers: {args.runs} runs each (seeds 0…{args.runs - 1}), BLAS threads "
        f"{os.environ['OPENBLAS_NUM_THREADS']} (swg-host is single-threaded); time in-process, "
        "covering reading the file, "
        "preparing direction and amplitude and the whole optimisation (Python start-up and imports excluded). "
        "Their time to 1 % is when a run's best point so far first had an RSS (evaluated by swg-host) within "
        "1 % of the best RSS; the median over runs, \"never\" when most runs never get there.",
        f"- swg-host: {args.ours_runs} runs (`--seed 1…{args.ours_runs}`) after one untimed run; wall time of the "
        "whole `swg-host fit FILE --json` process (start-up, reading, segmenting, fitting, baselines, JSON). Its "
        "time to 1 % is its total time (counted only if its RSS is within 1 % of the best).",
        f"- Caps: differential_evolution maxiter={args.de_maxiter} (scipy defaults otherwise, polish included), "
        f"pyswarms {args.pso_iters} iterations of 50 particles (c1=0.5, c2=0.3, w=0.9), least_squares 20 "
        "starts uniform in the same box (trf, analytic Jacobian, x_scale='jac').",
        "- Every RSS is the unweighted residual sum of squares computed by swg-host on the same direction and "
        "amplitude (the peers' parameters via `--compare`). On recordings swg-host weights the residuals by "
        "their total noise while fitting, so it does not minimise the unweighted RSS that is reported; the "
        "peers minimise exactly that figure.",
        "",
    ]
    text = "\n".join(header + sections)
    with open(os.path.join(args.out, "results.md"), "w") as f:
        f.write(text + "\n")
    print("\n" + text)


if __name__ == "__main__":
    main()
