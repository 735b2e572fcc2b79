"""Where each measured run's branches cross zero torque, against its rest reading (the mean
deflection of its first 4 s): the evidence of bench/real/FINDINGS.md §9 that a run's rest point
is set by the run before it. Python 3 standard library only.

    python3 bench/real/zero_crossings.py

Per run, in mrad from the rest reading: the middle of the deflection range, the falling branch
(global torque maximum to minimum) and the return branch (minimum to the end) where they cross
zero torque (mean of the crossings; — where the branch ends before it), and the loop's centre
line there (mean of the two)."""
import os
import re

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "data", "real", "sea-spring-2")
REST_S = 4.0


def read(path):
    rows = []
    for line in open(path):
        if line.startswith("#") or line.startswith("time_s") or not line.strip():
            continue
        rows.append(tuple(float(v) for v in line.split(",")))
    return rows


def crossing(branch):
    """Mean deflection where the torque crosses 0 along the branch [(θ, T)], or None."""
    found = [a + (b - a) * (0 - ta) / (tb - ta) for (a, ta), (b, tb) in zip(branch, branch[1:])
             if (ta <= 0 < tb) or (ta >= 0 > tb)]
    return sum(found) / len(found) if found else None


def mrad(value, rest):
    return "—" if value is None else f"{(value - rest) * 1e3:+.3f}"


def main():
    names = sorted((int(m.group(3)), f"{m.group(1)}-{m.group(2)}", f) for f in os.listdir(DATA)
                   if (m := re.match(r"kt-(\d+)-(\d+)-(\d+)-.*\.csv$", f)))
    print("| run | rest mrad | range middle | falling branch at T = 0 | return branch at T = 0 | centre line at T = 0 | torque at the end N·m |")
    print("|---|---|---|---|---|---|---|")
    for _, name, file in names:
        rows = read(os.path.join(DATA, file))
        window = [r for r in rows if r[0] - rows[0][0] < REST_S]
        rest = sum(r[1] for r in window) / len(window)
        theta, torque = [r[1] for r in rows], [r[2] for r in rows]
        top = max(range(len(rows)), key=lambda i: torque[i])
        bottom = min(range(len(rows)), key=lambda i: torque[i])
        falling = crossing(list(zip(theta[top:bottom], torque[top:bottom])))
        rising = crossing(list(zip(theta[bottom:], torque[bottom:])))
        centre = None if falling is None or rising is None else (falling + rising) / 2
        middle = (max(theta) + min(theta)) / 2
        end = sum(torque[-50:]) / 50
        print(f"| {name} | {rest * 1e3:.3f} | {mrad(middle, rest)} | {mrad(falling, rest)} | {mrad(rising, rest)} | "
              f"{mrad(centre, rest)} | {end:+.2f} |")


if __name__ == "__main__":
    main()
