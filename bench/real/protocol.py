"""Issue 16's protocol on the measured spring (data/real/sea-spring-2), run with the release
`swg-host` CLI. Python 3 standard library only. Called by bench/real.sh, which documents it.

Prints markdown tables on stdout; with --write-readme also replaces the marked section of
README.md. Runs are named <amps>-<test> (kt-<amps>-<test>-<id>-….csv)."""
import argparse
import concurrent.futures
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DATA = os.path.join(ROOT, "data", "real", "sea-spring-2")
HOST = os.path.join(ROOT, "target", "release", "swg-host")
README = os.path.join(ROOT, "README.md")
BEGIN, END = "<!-- real.sh begin -->", "<!-- real.sh end -->"

FITTED = ["1-4", "3-4", "5-1"]
# The prototype's held-out RMS from issue 16, mapped to runs as bench/real/FINDINGS.md does.
GOAL = {"1-5": 0.10, "1-6": 0.10, "2-4": 0.16, "2-5": 0.16, "2-6": 0.16, "3-5": 0.24, "3-6": 0.24,
        "4-4": 1.2, "4-5": 0.54, "4-6": 0.82, "5-2": 0.77, "5-3": 0.79}
KINDS = ["micro-slip", "genetic", "bouc-wen", "preisach"]
# The rest window: zero current for the first 5 s, read over the first 4.
REST_S = 4.0
# No-blow-up targets: the runs of about twice the current (there is no 6 A run: 3 A → 5 A).
DOUBLE = {1: 2, 2: 4, 3: 5}
# θ0 goal: within this fraction of the run's deflection range.
ZERO_GOAL = 0.02
WORKERS = 2
# A fit that has not finished by then is reported as such (some genetic fits of these runs do not
# finish: see the report's notes).
FIT_TIMEOUT = float(os.environ.get("REAL_FIT_TIMEOUT", "20"))
TIMED_OUT = "did not finish"


def runs():
    found = {}
    for name in sorted(os.listdir(DATA)):
        m = re.match(r"kt-(\d+)-(\d+)-(\d+)-.*\.csv$", name)
        if m:
            found[f"{m.group(1)}-{m.group(2)}"] = (int(m.group(3)), os.path.join(DATA, name))
    return {k: path for k, (_, path) in sorted(found.items(), key=lambda kv: kv[1][0])}


def read(path):
    """(header lines, rows [(t, θ, T)], data lines) of a recording."""
    header, rows, lines = [], [], []
    in_header = True
    with open(path) as f:
        for line in f:
            line = line.rstrip("\n")
            if in_header:
                header.append(line)
                in_header = not line.startswith("time_s")
                continue
            if line.strip():
                t, theta, torque = (float(v) for v in line.split(","))
                rows.append((t, theta, torque))
                lines.append(line)
    return header, rows, lines


def rest(rows):
    """Mean deflection and torque over the first REST_S seconds."""
    window = [r for r in rows if r[0] - rows[0][0] < REST_S]
    return sum(r[1] for r in window) / len(window), sum(r[2] for r in window) / len(window)


def host(*args, timeout=None):
    done = subprocess.run([HOST, *args], capture_output=True, text=True, timeout=timeout)
    if done.returncode != 0:
        raise RuntimeError(f"swg-host {' '.join(args)}: {done.stderr.strip()[-400:]}")
    return done.stdout


def fit(paths, kind, out, timeout=FIT_TIMEOUT):
    start = time.monotonic()
    result = json.loads(host("fit", *paths, "--model", kind, "--json", "--out", out, timeout=timeout))
    return result, time.monotonic() - start


def predict(params, path):
    if params is None:
        return None
    return json.loads(host("predict", params, path, "--json"))


def pool_map(fn, items):
    with concurrent.futures.ThreadPoolExecutor(WORKERS) as pool:
        return list(pool.map(fn, items))


def f3(x):
    return "—" if x is None else f"{x:.3f}"


def table(head, rows):
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def section_joint(paths, tmp, auto_timeout):
    """1. One fit on 1-4, 3-4, 5-1; predict every other run."""
    fitted = [paths[r] for r in FITTED]
    params, notes, fit_seconds = {}, [], {}
    for kind in KINDS:
        params[kind] = os.path.join(tmp, f"joint-{kind}.json")
        _, fit_seconds[kind] = fit(fitted, kind, params[kind])
    params["auto"] = os.path.join(tmp, "joint-auto.json")
    try:
        result, fit_seconds["auto"] = fit(fitted, "auto", params["auto"], timeout=auto_timeout)
        auto_label = f"auto ({'genetic' if result['model'].startswith('genetic') else result['model']})"
    except subprocess.TimeoutExpired:
        # auto's own rule (three runs: the middle amplitude, 3-4, held out; the kind with the lower
        # RMS on it is refitted on all three), from the named fits.
        held = {}
        for kind in KINDS:
            out = os.path.join(tmp, f"held-{kind}.json")
            fit([paths["1-4"], paths["5-1"]], kind, out)
            held[kind] = predict(out, paths["3-4"])["rms"]
        chosen = min(KINDS, key=held.get)
        params["auto"] = params[chosen]
        auto_label = f"auto's rule, emulated ({chosen})"
        named = " / ".join(f"{kind} {fit_seconds[kind]:.2f} s" for kind in KINDS)
        held_out = ", ".join(f"{kind} {held[kind]:.3f}" for kind in KINDS)
        notes.append(f"`swg-host fit {' '.join(FITTED)} --model auto` did not finish within {auto_timeout:.0f} s "
                     f"(named kinds: {named}); the auto column applies auto's rule with named fits: fitted on "
                     f"1-4 + 5-1, held-out RMS on 3-4 {held_out} N·m → {chosen}, refitted on all three.")
    targets = [r for r in paths if r not in FITTED]
    jobs = [(label, run) for label in ["auto", *KINDS] for run in targets]
    results = dict(zip(jobs, pool_map(lambda job: predict(params[job[0]], paths[job[1]]), jobs)))
    rows, missed = [], []
    for run in targets:
        a = results[("auto", run)]
        ok = a["rms"] <= GOAL[run]
        if not ok:
            missed.append(f"{run}: {a['rms']:.3f} > {GOAL[run]:.2f} N·m ({a['rms'] / GOAL[run]:.2f}×)")
        kinds = [f"{results[(k, run)]['rms']:.3f}" + ("" if results[(k, run)]["rms"] <= GOAL[run] else " ✗")
                 for k in KINDS]
        rows.append([run, f"{GOAL[run]:.2f}", f3(a["rms"]), f3(a["within_range_rms"]), a["beyond_range_samples"],
                     "pass" if ok else "**fail**", *kinds])
    text = table(["run", "goal", auto_label + " RMS", "within-range RMS", "beyond range", "goal met",
                  *[f"{kind} RMS" for kind in KINDS]], rows)
    return text, notes, missed, results


def section_repeat(paths, single, joint_results):
    """2. Per amplitude, one repeat fitted alone predicts the others."""
    by_amps = {}
    for run in paths:
        by_amps.setdefault(int(run.split("-")[0]), []).append(run)
    jobs = [(kind, a, b) for kind in KINDS for group in by_amps.values() for a in group for b in group if a != b]
    rms = dict(zip(jobs, pool_map(lambda j: (predict(single[(j[0], j[1])], paths[j[2]]) or {}).get("rms"), jobs)))
    rows = []
    for amps, group in by_amps.items():
        cells = []
        for kind in KINDS:
            values = [rms[(kind, a, b)] for a in group for b in group if a != b]
            done = [v for v in values if v is not None]
            cell = f"{sum(done) / len(done):.3f} ({max(done):.3f})" if done else TIMED_OUT
            cells.append(cell + (f", {len(done)} of {len(values)} pairs" if len(done) < len(values) else ""))
        joint = [joint_results[("auto", r)]["rms"] for r in group if ("auto", r) in joint_results]
        cells.append(f"{sum(joint) / len(joint):.3f}" if joint else "—")
        rows.append([f"{amps} A", ", ".join(group), *cells])
    return table(["amps", "repeats", *[f"{kind}: mean (max) of 6 pairs" for kind in KINDS],
                  "joint fit (auto), mean on the held-out repeats"], rows)


def line_fit(rows):
    """Least-squares T = k·x + c on x = θ − θ_rest, T − T_rest."""
    theta_r, torque_r = rest(rows)
    xs = [r[1] - theta_r for r in rows]
    ys = [r[2] - torque_r for r in rows]
    n, sx, sy = len(xs), sum(xs), sum(ys)
    sxx = sum(x * x for x in xs)
    sxy = sum(x * y for x, y in zip(xs, ys))
    k = (n * sxy - sx * sy) / (n * sxx - sx * sx)
    return k, (sy - k * sx) / n


def line_rms(line, rows):
    k, c = line
    theta_r, torque_r = rest(rows)
    return math.sqrt(sum((k * (r[1] - theta_r) + c + torque_r - r[2]) ** 2 for r in rows) / len(rows))


def deflection_range(rows):
    return max(r[1] for r in rows) - min(r[1] for r in rows)


def section_blowup(paths, data, single):
    """3. A fit on one run predicts the runs of about twice its current, against a straight line."""
    cases = [(src, dst) for src in paths for dst in paths
             if DOUBLE.get(int(src.split("-")[0])) == int(dst.split("-")[0])]
    jobs = [(kind, src, dst) for kind in KINDS for src, dst in cases]
    out = dict(zip(jobs, pool_map(lambda j: predict(single[(j[0], j[1])], paths[j[2]]), jobs)))
    rows, worse = [], []
    for src, dst in cases:
        line = line_rms(line_fit(data[src]), data[dst])
        ratio = deflection_range(data[dst]) / deflection_range(data[src])
        cells = []
        for kind in KINDS:
            p = out[(kind, src, dst)]
            if p is None:
                cells.append(f"fit {TIMED_OUT}")
                continue
            bad = p["rms"] > line
            if bad:
                worse.append(f"{kind} {src} → {dst}: {p['rms']:.3f} vs line {line:.3f} N·m ({p['rms'] / line:.2f}×)")
            cells.append(f"{p['rms']:.3f}{' ✗' if bad else ''} ({p['beyond_range_samples']}, "
                         f"{p['max_excess_rad'] * 1e3:.2f})")
        rows.append([f"{src} → {dst}", f"{ratio:.1f}×", f"{line:.3f}", *cells])
    head = ["fitted → predicted", "deflection range", "line k·x + c RMS",
            *[f"{kind} RMS (beyond-range samples, max excess mrad)" for kind in KINDS]]
    return table(head, rows), worse, len(cases)


def cut_recording(path, src_rows, tmp, name, cut_s):
    """The recording without its first cut_s seconds and without `# start: rest`."""
    header, rows, lines = read(path)
    kept = [line for r, line in zip(rows, lines) if r[0] - rows[0][0] >= cut_s]
    out = os.path.join(tmp, f"cut-{name}.csv")
    with open(out, "w") as f:
        f.write("\n".join([h for h in header if not h.startswith("# start")] + kept) + "\n")
    return out


def zero_case(name, path, rows, tmp, probe):
    """θ0 fitted on the run without its rest: the cut starts at REST_S and moves on in 0.5 s steps
    while swg-host still finds a rest window (the rest of the 5 s at zero current, then the slow
    ramp's first samples)."""
    cut = REST_S
    while True:
        trimmed = cut_recording(path, rows, tmp, name, cut)
        # Whether predict finds a rest window depends on the recording only, not on the params.
        if "origin" not in predict(probe, trimmed):
            break
        cut += 0.5
        if cut > 15:
            raise RuntimeError(f"{name}: swg-host still finds a rest window after cutting {cut} s")
    zeros = {}
    for kind in KINDS:
        params = os.path.join(tmp, f"zero-{kind}-{name}.json")
        try:
            result, _ = fit([trimmed], kind, params)
            zeros[kind] = (result["params"]["zero"], result["runs"][0]["origin"]["zero_se_rad"] or 0.0)
        except subprocess.TimeoutExpired:
            zeros[kind] = f"fit {TIMED_OUT}"
        except RuntimeError as error:
            zeros[kind] = "fit failed: " + str(error).split("fit failed: ")[-1]
    # `auto`: the chosen kind's θ0 ± its uncertainty, and the span over every kind it tried.
    try:
        result, _ = fit([trimmed], "auto", os.path.join(tmp, f"zero-auto-{name}.json"))
        origin = result["runs"][0]["origin"]
        tried = [c["fitted_zero_rad"] for c in result["candidates"] if "fitted_zero_rad" in c]
        zeros["auto"] = (result["model"], origin["zero_rad"], origin["zero_se_rad"] or 0.0, min(tried), max(tried))
    except subprocess.TimeoutExpired:
        zeros["auto"] = f"fit {TIMED_OUT}"
    except RuntimeError as error:
        said = str(error)
        zeros["auto"] = ("refused: too few samples to hold out and judge the kinds" if "holds out" in said
                         else "fit failed: " + said[-90:])
    return cut, zeros


def section_zero(paths, data, tmp, single):
    """4. θ0 fitted with the rest window cut away, against the deflection read at rest."""
    names = list(paths)
    found = dict(zip(names, pool_map(
        lambda n: zero_case(n, paths[n], data[n], tmp, single[("micro-slip", n)] or single[("genetic", n)]), names)))
    rows, missed, covered = [], [], 0
    judged, auto_covered, span_covered = 0, 0, 0
    for name in names:
        cut, zeros = found[name]
        at_rest, _ = rest(data[name])
        span = deflection_range(data[name])
        cells = []
        for kind in KINDS:
            if isinstance(zeros[kind], str):
                cells.append(zeros[kind] + " ✗")
                missed.append(f"{kind} {name}: {zeros[kind]}")
                continue
            zero, se = zeros[kind]
            error = zero - at_rest
            share = abs(error) / span
            covered += abs(error) <= se
            if share > ZERO_GOAL:
                missed.append(f"{kind} {name}: θ0 off by {error * 1e3:+.3f} mrad = {share * 100:.1f} % of the range")
            cells.append(f"{zero * 1e3:.3f} ± {se * 1e3:.3f} ({error * 1e3:+.3f}, {share * 100:.1f} %"
                         f"{' ✗' if share > ZERO_GOAL else ''})")
        auto = zeros["auto"]
        if isinstance(auto, str):
            cells.append(auto)
        else:
            model, zero, se, lo, hi = auto
            judged += 1
            chosen_in, span_in = abs(zero - at_rest) <= se, lo <= at_rest <= hi
            auto_covered += chosen_in
            span_covered += span_in
            cells.append(f"{model} {zero * 1e3:.3f} ± {se * 1e3:.3f}{'' if chosen_in else ' ✗'}; "
                         f"{lo * 1e3:.3f} … {hi * 1e3:.3f}{'' if span_in else ' ✗'}")
        rows.append([name, f"{cut:.1f}", f"{at_rest * 1e3:.3f}", f"{span * 1e3:.3f}", *cells])
    head = ["run", "cut s", "θ rest mrad", "range mrad",
            *[f"{kind} θ0 ± its reported uncertainty, mrad (error, % of range)" for kind in KINDS],
            "auto: the chosen kind's θ0 ± its uncertainty; the span of every kind's θ0, mrad"]
    note = (f"The rest deflection lies within the reported uncertainty (θ0 ± it) in {covered} of "
            f"{len(names) * len(KINDS)} fits. With `auto` (✗: the rest reading outside), within the chosen "
            f"kind's θ0 ± its uncertainty in {auto_covered} of {judged} runs, within the span of the θ0s "
            f"of the kinds it tried (the report's kinds table) in {span_covered} of {judged}.")
    return table(head, rows) + "\n\n" + note, missed


def section_folds(paths, tmp):
    """5. Each fitted run held out in turn: the other two fitted, the held-out one predicted."""
    jobs = [(kind, held) for kind in KINDS for held in FITTED]

    def held_out_rms(job):
        kind, held = job
        out = os.path.join(tmp, f"fold-{kind}-{held}.json")
        try:
            fit([paths[r] for r in FITTED if r != held], kind, out)
        except subprocess.TimeoutExpired:
            return None
        return predict(out, paths[held])["rms"]

    rms = dict(zip(jobs, pool_map(held_out_rms, jobs)))
    rows = []
    for kind in KINDS:
        figures = [rms[(kind, held)] for held in FITTED]
        pooled = None if None in figures else math.sqrt(sum(x * x for x in figures) / len(figures))
        rows.append([kind, *(f3(x) for x in figures), f3(pooled)])
    return table(["kind", *(f"{r} held out" for r in FITTED), "root mean square of the three"], rows)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--write-readme", action="store_true")
    parser.add_argument("--auto-timeout", type=float, default=float(os.environ.get("REAL_AUTO_TIMEOUT", "30")))
    args = parser.parse_args()
    if not os.access(HOST, os.X_OK):
        sys.exit(f"{HOST} missing: run `cargo build --release -p swg-host` first")
    started = time.monotonic()
    paths = runs()
    data = {name: read(path)[1] for name, path in paths.items()}
    with tempfile.TemporaryDirectory() as tmp:
        single = {}
        for kind in KINDS:
            for name, path in paths.items():
                single[(kind, name)] = os.path.join(tmp, f"single-{kind}-{name}.json")
        def single_fit(key):
            try:
                fit([paths[key[1]]], key[0], single[key])
            except subprocess.TimeoutExpired:
                single[key] = None
                notes.append(f"`swg-host fit {key[1]} --model {key[0]}` did not finish within {FIT_TIMEOUT:.0f} s.")
        notes = []
        pool_map(single_fit, list(single))
        joint, joint_notes, joint_missed, joint_results = section_joint(paths, tmp, args.auto_timeout)
        notes = joint_notes + sorted(notes)
        repeat = section_repeat(paths, single, joint_results)
        blowup, worse, cases = section_blowup(paths, data, single)
        zero, zero_missed = section_zero(paths, data, tmp, single)
        folds = section_folds(paths, tmp)
    seconds = time.monotonic() - started
    report = "\n\n".join([
        "**1. One fit on " + ", ".join(FITTED) + " together, every other run predicted** (RMS N·m; "
        "goal = the prototype's figure in issue 16; ✗ = over the goal)",
        joint, *notes,
        "**2. Repeatability: one repeat fitted alone predicts the other two** (RMS N·m)",
        repeat,
        "**3. No blow-up: one run fitted alone predicts the runs of about twice its current** (3 A → 5 A; "
        "RMS N·m over every sample; the line is fitted by least squares on the same run, both zeroed on "
        "their first 4 s; ✗ = worse than the line)",
        blowup,
        "**4. θ0 fitted on each run with its rest window cut away** (cut: the first seconds removed until "
        "`swg-host` finds no rest window; against the mean deflection of the first 4 s; goal ≤ 2 % of the "
        "run's deflection range)",
        zero,
        "**5. Which held-out run ranks the kinds** (" + ", ".join(FITTED) + ": each held out in turn, the "
        "other two fitted with the kind named, RMS N·m on the held-out run; `auto` holds out "
        + FITTED[0] + " and " + FITTED[1] + " whole and the middle leg of " + FITTED[2] + ", the largest)",
        folds,
        "**Goals missed**: "
        + (f"1. {len(joint_missed)} of {len(GOAL)} runs: " + "; ".join(joint_missed) if joint_missed else "1. none")
        + (f". 3. {len(worse)} of {cases * len(KINDS)}: " + "; ".join(worse) if worse else ". 3. none")
        + (f". 4. {len(zero_missed)} of {len(paths) * len(KINDS)}: " + "; ".join(zero_missed) if zero_missed else ". 4. none")
        + ".",
        f"({seconds:.0f} s, `bash bench/real.sh`)",
    ])
    print(report)
    if args.write_readme:
        text = open(README).read()
        if BEGIN not in text or END not in text:
            sys.exit(f"README.md has no {BEGIN} … {END} section")
        head, rest_of = text.split(BEGIN, 1)
        _, tail = rest_of.split(END, 1)
        with open(README, "w") as f:
            f.write(head + BEGIN + "\n" + report + "\n" + END + tail)


if __name__ == "__main__":
    main()
