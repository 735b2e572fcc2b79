"""A catalogue of gear-like OpenSees uniaxial materials: torque (N·m) against torsional deflection (rad).

OpenSees has no units: its strain is our deflection θ in rad, its stress our torque T in N·m, its
tangent our stiffness dT/dθ in N·m/rad. Every material is a `Parallel` of OpenSees' own elements,
built fresh (virgin, at rest) for each run. Gear-like scale, checked by `verify.py`: about 28 N·m at
the benchmark's amplitude of 1.168 mrad, a loop 2–4 % of the peak wide at θ = 0, and a stiffness
that rises 2–4× from zero to the peak, as a strain wave gear's does.

The stiffening spring common to most families is T = k1·θ + k3·θ³ (a Duffing spring, each side
with its own k1, k3 where asymmetric), tabulated for `ElasticMultiLinear` at knots every 10 µrad
over ±3 mrad (601 knots, exact at the knots; between them the chord, whose slope is off the
cubic's by at most 3·k3·θ·10 µrad, under 1 % of the stiffness at the peak). OpenSees offers no
smooth polynomial elastic material; beyond ±3 mrad it continues with the last chord's slope.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist
from typing import Callable

import numpy as np
import openseespy.opensees as ops

# The benchmark's deflection amplitude (tests/prediction_corpus.rs), rad.
AMPLITUDE_RAD = 1.168e-3

SPRING_SPAN_RAD = 3e-3
SPRING_KNOT_RAD = 1e-5


class Tags:
    """Hands out OpenSees material tags in order."""

    def __init__(self) -> None:
        self.last = 0

    def next(self) -> int:
        self.last += 1
        return self.last


def stiffening_spring(tags: Tags, k1: float, k3: float, k1_neg: float | None = None, k3_neg: float | None = None) -> int:
    """T = k1·θ + k3·θ³ for θ ≥ 0 and k1_neg·θ + k3_neg·θ³ for θ < 0 (defaults: the + side's),
    tabulated for ElasticMultiLinear (see the module's docstring)."""
    k1_neg = k1 if k1_neg is None else k1_neg
    k3_neg = k3 if k3_neg is None else k3_neg
    knots = round(SPRING_SPAN_RAD / SPRING_KNOT_RAD)
    strains = [i * SPRING_KNOT_RAD for i in range(-knots, knots + 1)]
    stresses = [(k1 * x + k3 * x**3) if x >= 0 else (k1_neg * x + k3_neg * x**3) for x in strains]
    return elastic_multilinear(tags, strains, stresses)


def elastic_multilinear(tags: Tags, strains: list[float], stresses: list[float]) -> int:
    tag = tags.next()
    ops.uniaxialMaterial("ElasticMultiLinear", tag, 0.0, "-strain", *strains, "-stress", *stresses)
    return tag


def parallel(tags: Tags, members: list[int]) -> int:
    tag = tags.next()
    ops.uniaxialMaterial("Parallel", tag, *members)
    return tag


def slip_elements(tags: Tags, slips_rad: list[float], stiffness_nm_per_rad: float) -> list[int]:
    """Elasto-slip elements (`ElasticPP`): each a spring of the given stiffness that slips at its
    deflection, i.e. at the torque stiffness·slip (a Maxwell-slip/Iwan element)."""
    members = []
    for slip in slips_rad:
        tag = tags.next()
        ops.uniaxialMaterial("ElasticPP", tag, stiffness_nm_per_rad, slip)
        members.append(tag)
    return members


def lognormal_quantiles(median: float, sigma: float, count: int) -> list[float]:
    """The quantiles (i + ½)/count of a log-normal distribution."""
    normal = NormalDist(math.log(median), sigma)
    return [math.exp(normal.inv_cdf((i + 0.5) / count)) for i in range(count)]


def log_grid(low: float, high: float, count: int) -> list[float]:
    return [low * (high / low) ** (i / (count - 1)) for i in range(count)]


@dataclass(frozen=True)
class Material:
    """A named gear: what it is, its parameters (SI units, in the names), and how it is built."""

    name: str
    summary: str
    params: dict
    builder: Callable[[Tags, dict], int]

    def build(self) -> int:
        """Defines the material in a wiped OpenSees domain and returns its tag."""
        ops.wipe()
        return self.builder(Tags(), self.params)


def build_steel02(tags: Tags, p: dict) -> int:
    steel = tags.next()
    ops.uniaxialMaterial(
        "Steel02", steel, p["fy_nm"], p["e0_nm_per_rad"], p["b"], p["r0"], p["cr1"], p["cr2"]
    )
    return parallel(tags, [steel, stiffening_spring(tags, p["k1_nm_per_rad"], p["k3_nm_per_rad3"])])


def build_bouc_wen(tags: Tags, p: dict) -> int:
    bouc_wen = tags.next()
    ops.uniaxialMaterial(
        "BoucWen", bouc_wen, p["alpha"], p["ko_nm_per_rad"], p["n"], p["gamma"], p["beta"], p["a0"],
        0.0, 0.0, 0.0,  # deltaA, deltaNu, deltaEta: no degradation
    )
    return parallel(tags, [bouc_wen, stiffening_spring(tags, p["k1_nm_per_rad"], p["k3_nm_per_rad3"])])


def build_hysteretic(tags: Tags, p: dict) -> int:
    hysteretic = tags.next()
    backbone = [v for point in p["backbone_nm_rad"] for v in point]
    negative = [-v for point in p["backbone_nm_rad"] for v in point]
    # pinchX = pinchY = 1 (no pinching), damage1 = damage2 = 0, beta = 0 (unloading at the
    # initial stiffness): what is left is the peak-oriented reloading.
    ops.uniaxialMaterial("Hysteretic", hysteretic, *backbone, *negative, 1.0, 1.0, 0.0, 0.0, 0.0)
    return parallel(tags, [hysteretic, stiffening_spring(tags, p["k1_nm_per_rad"], p["k3_nm_per_rad3"])])


def iwan_slips(p: dict) -> list[float]:
    return lognormal_quantiles(p["slip_median_rad"], p["slip_log_sigma"], p["elements"])


def build_iwan(tags: Tags, p: dict) -> int:
    elements = slip_elements(tags, iwan_slips(p), p["slip_stiffness_nm_per_rad"] / p["elements"])
    return parallel(tags, [*elements, stiffening_spring(tags, p["k1_nm_per_rad"], p["k3_nm_per_rad3"])])


def catalogue_curve(p: dict) -> tuple[list[float], list[float]]:
    """The catalogue's three segments, point-symmetric: K1 up to T1, K2 up to T2, K3 beyond
    (to ±3 mrad, then OpenSees continues with K3)."""
    k1, k2, k3 = p["k1_nm_per_rad"], p["k2_nm_per_rad"], p["k3_nm_per_rad"]
    t1, t2 = p["t1_nm"], p["t2_nm"]
    theta1 = t1 / k1
    theta2 = theta1 + (t2 - t1) / k2
    end = SPRING_SPAN_RAD
    positive = [(theta1, t1), (theta2, t2), (end, t2 + k3 * (end - theta2))]
    points = [(-x, -t) for x, t in reversed(positive)] + [(0.0, 0.0)] + positive
    return [x for x, _ in points], [t for _, t in points]


def build_catalogue(tags: Tags, p: dict) -> int:
    spring = elastic_multilinear(tags, *catalogue_curve(p))
    slips = log_grid(p["slip_min_rad"], p["slip_max_rad"], p["elements"])
    elements = slip_elements(tags, slips, p["slip_stiffness_nm_per_rad"] / p["elements"])
    return parallel(tags, [spring, *elements])


def build_asymmetric(tags: Tags, p: dict) -> int:
    spring = stiffening_spring(
        tags,
        p["k1_nm_per_rad"] * p["positive_scale"],
        p["k3_nm_per_rad3"] * p["positive_scale"],
        p["k1_nm_per_rad"] * p["negative_scale"],
        p["k3_nm_per_rad3"] * p["negative_scale"],
    )
    slips = log_grid(p["slip_min_rad"], p["slip_max_rad"], p["elements"])
    elements = slip_elements(tags, slips, p["slip_stiffness_nm_per_rad"] / p["elements"])
    return parallel(tags, [spring, *elements])


MATERIALS: dict[str, Material] = {
    m.name: m
    for m in [
        Material(
            "steel02",
            "Menegotto–Pinto (Steel02: smooth branches, isotropic hardening off) in Parallel with the "
            "stiffening spring",
            {
                "fy_nm": 0.42, "e0_nm_per_rad": 4000.0, "b": 0.02, "r0": 18.0, "cr1": 0.925, "cr2": 0.15,
                "k1_nm_per_rad": 12000.0, "k3_nm_per_rad3": 8.5e9,
            },
            build_steel02,
        ),
        Material(
            "bouc-wen",
            "OpenSees' BoucWen (no degradation; T = alpha·ko·θ + (1 − alpha)·ko·z, "
            "dz/dθ = a0 − |z|^n·(gamma + beta·sign(dθ·z))) in Parallel with the stiffening spring",
            {
                "alpha": 0.05, "ko_nm_per_rad": 1500.0, "n": 1.5, "gamma": 9.6e4, "beta": 9.6e4, "a0": 1.0,
                "k1_nm_per_rad": 12000.0, "k3_nm_per_rad3": 8.5e9,
            },
            build_bouc_wen,
        ),
        Material(
            "hysteretic",
            "the peak-oriented Hysteretic material (trilinear backbone, point-symmetric; reloading aims "
            "at the historic peak; no pinching, no damage, unloading at the initial stiffness) in "
            "Parallel with the stiffening spring",
            {
                "backbone_nm_rad": [[0.42, 0.05e-3], [0.77, 0.8e-3], [0.9, 3e-3]],
                "k1_nm_per_rad": 12000.0, "k3_nm_per_rad3": 8.5e9,
            },
            build_hysteretic,
        ),
        Material(
            "iwan",
            "an Iwan/Maxwell-slip gear: ElasticPP elements of equal stiffness whose slip deflections are "
            "the quantiles of a log-normal distribution, in Parallel with the stiffening spring",
            {
                "elements": 100, "slip_stiffness_nm_per_rad": 1600.0,
                "slip_median_rad": 0.35e-3, "slip_log_sigma": 0.9,
                "k1_nm_per_rad": 11500.0, "k3_nm_per_rad3": 8.5e9,
            },
            build_iwan,
        ),
        Material(
            "catalogue",
            "a harmonic-drive catalogue spring (ElasticMultiLinear: K1 up to T1, K2 up to T2, K3 beyond, "
            "point-symmetric, kinked) in Parallel with a few ElasticPP slip elements on a log grid",
            {
                "k1_nm_per_rad": 14000.0, "k2_nm_per_rad": 26000.0, "k3_nm_per_rad": 42000.0,
                "t1_nm": 7.0, "t2_nm": 19.0,
                "elements": 6, "slip_stiffness_nm_per_rad": 2500.0, "slip_min_rad": 20e-6, "slip_max_rad": 0.8e-3,
            },
            build_catalogue,
        ),
        Material(
            "asymmetric",
            "a stiffening spring whose + side is softer than its − side (ElasticMultiLinear, the cubic "
            "scaled by positive_scale and negative_scale) in Parallel with a few ElasticPP slip elements",
            {
                "k1_nm_per_rad": 12000.0, "k3_nm_per_rad3": 8.5e9, "positive_scale": 0.88, "negative_scale": 1.12,
                "elements": 6, "slip_stiffness_nm_per_rad": 2500.0, "slip_min_rad": 20e-6, "slip_max_rad": 0.8e-3,
            },
            build_asymmetric,
        ),
    ]
}


class UnknownMaterial(ValueError):
    def __init__(self, name: str) -> None:
        super().__init__(f"unknown material {name!r}: expected one of {', '.join(MATERIALS)}")


def material(name: str) -> Material:
    try:
        return MATERIALS[name]
    except KeyError:
        raise UnknownMaterial(name) from None


def drive(name: str, deflection_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drives a virgin copy of the material through the deflections in order; returns the torque
    (N·m) and tangent stiffness (N·m/rad) after each. `setStrain` commits every step, so the
    material's history is exactly this path."""
    tag = material(name).build()
    ops.testUniaxialMaterial(tag)
    torque = np.empty(len(deflection_rad))
    tangent = np.empty(len(deflection_rad))
    for i, theta in enumerate(deflection_rad):
        ops.setStrain(float(theta))
        torque[i] = ops.getStress()
        tangent[i] = ops.getTangent()
    ops.wipe()
    return torque, tangent
