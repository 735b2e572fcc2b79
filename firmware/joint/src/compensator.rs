use crate::direct::DirectMath;
use crate::fast::FastMath;
use core::cell::UnsafeCell;
use core::sync::atomic::{fence, AtomicBool, AtomicU32, AtomicU8, Ordering};
use model_core::Evaluator;
use swg_protocol::{Compensation, ErrorReply, EvalPath, Feedforward, JointParams};

/// Largest plausible torsional deflection, rad (≈ 5.7°; strain wave gears deflect a few mrad).
/// Beyond it a reading is an encoder fault: the tick is skipped without touching the model's
/// memory, so one glitch cannot leave a false turning point behind. Within it every accepted
/// set evaluates in f32 ([`JointParams::validate`] checks that, on the host too).
pub const MAX_DEFLECTION: f32 = swg_protocol::MAX_DEFLECTION;

/// A slot for a validated parameter set as the tick uses it: its evaluator, prepared at rest
/// (in service only when `ready`), and the two numbers of the joint the tick needs (the link
/// keeps the whole set for reads and commits).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Installed {
    /// Written over in place by each set staged here (never put together on the link's stack).
    evaluator: Evaluator<f32>,
    /// The evaluator holds a validated set: the tick evaluates it.
    ready: bool,
    gear_ratio: f32,
    torque_limit: f32,
    /// [`EvalPath::Fast`] runs the evaluator with [`FastMath`] (model-core's `has_fast_path`).
    fast: bool,
    /// The deflections θ both plausible and within the spring's identified range, as a centre
    /// and a half-width (a little narrower than exact): one comparison for both on a tick.
    usual: Window,
}

/// θ with |θ − centre| ≤ half_width, rad.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Window {
    centre: f32,
    half_width: f32,
}

impl Window {
    /// [lo, hi] narrowed by a few f32 roundings of its ends, so that no θ in it lies beyond
    /// them however the tick rounds x = θ − θ0 (the tick checks the θ outside it exactly).
    fn within(lo: f32, hi: f32) -> Self {
        let centre = 0.5 * lo + 0.5 * hi;
        let margin = 1.0e-6 * (lo.abs() + hi.abs()) + f32::MIN_POSITIVE;
        Window { centre, half_width: (0.5 * hi - 0.5 * lo - margin).max(0.0) }
    }

    #[inline(always)]
    fn holds(&self, theta: f32) -> bool {
        (theta - self.centre).abs() <= self.half_width
    }
}

impl Installed {
    fn empty() -> Self {
        Installed {
            evaluator: Evaluator::idle(),
            ready: false,
            gear_ratio: 0.0,
            torque_limit: 0.0,
            fast: false,
            usual: Window { centre: 0.0, half_width: 0.0 },
        }
    }

    /// Validates `params` and prepares their evaluator at rest in this slot: the slow part of
    /// staging a set (the range checks, the fast path's constants), done where time does not
    /// matter, in place (no second set on the link's stack). The slot is left out of service
    /// where the set is refused.
    fn prepare(&mut self, params: &JointParams) -> Result<(), ErrorReply> {
        self.ready = false;
        params.prepare_evaluator(&mut self.evaluator)?;
        self.ready = true;
        (self.gear_ratio, self.torque_limit) = (params.gear_ratio, params.torque_limit);
        self.fast = params.model.has_fast_path();
        let [lo, hi] = params.model.spring.range.map(|edge| edge + params.model.zero);
        self.usual = Window::within(lo.max(-MAX_DEFLECTION), hi.min(MAX_DEFLECTION));
        Ok(())
    }
}

/// The feed-forward of one joint: parameters, the model's memory, evaluation, clamping.
///
/// A new set is validated and prepared completely by [`Stager::stage`] and takes effect at
/// the start of the next [`Ticker::tick`], so no tick ever sees half of it; a refused set
/// leaves the previous one (and its memory) active.
///
/// **Memory and parameter changes.** The installed model runs stateful from rest
/// (model-core's `Evaluator`: the genetic kind with the set's direction band as its reversal
/// band and `TURNING_POINTS` turning points, the micro-slip kind with `SLIP_ELEMENTS`). A
/// staged set is prepared at rest, and the memory is reset at exactly one moment: when that
/// set is activated, at the start of the first tick after it was staged, before that tick's
/// sample is evaluated. That tick therefore starts from rest (the virgin curve) with the new
/// set, whatever the old one had remembered, as after a reboot; writing the same set again
/// resets too. A history recorded under other parameters has no meaning for the new ones
/// (turning points hold torques of the old model), so none is carried over. Between two ticks
/// nothing else touches the memory: refused sets, reads and commits leave it as it is.
///
/// **Two slots, no lock.** The set in use and the next one live in two slots, shared by the
/// link (lowest priority) and the tick (highest) through [`Compensator::split`]: the link's
/// [`Stager`] prepares a set in the slot the tick does not use and raises a flag; the
/// [`Ticker`] switches slots at the start of its next tick and lowers it. So a set is
/// prepared in place, never copied, and the tick that activates it flips an index (a copy
/// made that tick would be the slowest of all). While the flag is up the link stages nothing
/// more (the link answers [`ErrorReply::Busy`]; it waits for the next tick).
pub struct Compensator {
    slots: [UnsafeCell<Installed>; 2],
    /// The slot the tick evaluates, 0 or 1: written by the tick only.
    active: AtomicU8,
    /// The other slot holds a set for the next tick: raised by the link once the set is in
    /// place, lowered by the tick when it switches to it.
    staged: AtomicBool,
    /// The active set's samples beyond its spring's identified range, since it was activated:
    /// written by the tick only, read by the link.
    beyond_range: AtomicU32,
    /// The largest excess of those, rad, as f32 bits (for values ≥ 0 the bits order as the
    /// values do).
    max_excess: AtomicU32,
}

// SAFETY: `Sync` lets the two halves of `split` (each holding `&Compensator`) live at two
// interrupt priorities. The invariant that makes their `UnsafeCell` accesses exclusive:
// - Ownership. The `Ticker` is the only one to touch the slot `active` names, and the only
//   writer of `active`; the `Stager` touches the other slot, and only while `staged` is down.
//   `split` takes `&mut self`, so there is one `Stager` and one `Ticker` (neither is `Clone`),
//   and no other `&Compensator` while they exist: `Clone` and `Debug` (through `&self`) run
//   only when no half does.
// - A slot changes hands only at `Ticker::activate_staged`, and only when `staged` is up,
//   while the `Stager` leaves both slots alone (it stages nothing until `staged` is down).
// - Link → tick: the `Stager` raises `staged` with release ordering after its last write to
//   the slot; the tick reads it and, when up, fences with acquire ordering before it switches
//   to the slot: the tick sees the whole set.
// - Tick → link: the tick lowers `staged` with release ordering after switching, and every
//   access it made to the slot it gave up came before that (in its previous ticks); the
//   `Stager` reads `staged` with acquire ordering (`has_room`) before it writes that slot, and
//   reads `active` after it, so it picks the slot the tick gave up and writes it only after
//   the tick's last access.
// The tick's `&mut Installed` lives within one `tick` call and `Ticker::active`'s `&Installed`
// within a `&self` call of the `Ticker`: never both.
#[allow(unsafe_code)]
unsafe impl Sync for Compensator {}

impl Compensator {
    pub fn new() -> Self {
        Compensator {
            slots: [UnsafeCell::new(Installed::empty()), UnsafeCell::new(Installed::empty())],
            active: AtomicU8::new(0),
            staged: AtomicBool::new(false),
            beyond_range: AtomicU32::new(0),
            max_excess: AtomicU32::new(0),
        }
    }

    /// The active set's samples beyond its spring's identified range since it was activated,
    /// and the largest excess of those, rad.
    pub fn beyond_range(&self) -> (u32, f32) {
        (self.beyond_range.load(Ordering::Relaxed), f32::from_bits(self.max_excess.load(Ordering::Relaxed)))
    }

    /// The link's half (staging sets) and the tick's (evaluating them), for a board's two
    /// priorities.
    pub fn split(&mut self) -> (Stager<'_>, Ticker<'_>) {
        let compensator = &*self;
        (Stager { compensator }, Ticker { compensator })
    }

    /// The tick's half.
    pub fn ticker(&mut self) -> Ticker<'_> {
        self.split().1
    }

    /// Validates `params` and prepares them, at rest, for the next tick ([`Stager::stage`]).
    pub fn stage(&mut self, params: JointParams) -> Result<(), ErrorReply> {
        self.split().0.stage(&params)
    }

    /// One control tick ([`Ticker::tick`]).
    #[inline(always)]
    pub fn tick(&mut self, input_angle: f32, output_angle: f32, path: EvalPath) -> Feedforward {
        self.ticker().tick(input_angle, output_angle, path)
    }

    /// The slot `index` (0: the first, else the second).
    fn slot(&self, index: u8) -> &UnsafeCell<Installed> {
        let [first, second] = &self.slots;
        if index == 0 {
            first
        } else {
            second
        }
    }
}

impl Default for Compensator {
    fn default() -> Self {
        Self::new()
    }
}

impl Clone for Compensator {
    fn clone(&self) -> Self {
        // SAFETY: `&self` exists only while no half of `split` does (they borrow `&mut self`),
        // so nothing writes the slots meanwhile.
        #[allow(unsafe_code)]
        let slots = self.slots.each_ref().map(|slot| UnsafeCell::new(unsafe { *slot.get() }));
        Compensator {
            slots,
            active: AtomicU8::new(self.active.load(Ordering::Relaxed)),
            staged: AtomicBool::new(self.staged.load(Ordering::Relaxed)),
            beyond_range: AtomicU32::new(self.beyond_range.load(Ordering::Relaxed)),
            max_excess: AtomicU32::new(self.max_excess.load(Ordering::Relaxed)),
        }
    }
}

impl core::fmt::Debug for Compensator {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Compensator")
            .field("active", &self.active.load(Ordering::Relaxed))
            .field("staged", &self.staged.load(Ordering::Relaxed))
            .finish_non_exhaustive()
    }
}

/// The link's half of a [`Compensator`]: stages sets.
pub struct Stager<'a> {
    compensator: &'a Compensator,
}

impl Stager<'_> {
    /// Whether the tick has taken the last staged set (a new one may be staged).
    pub fn has_room(&self) -> bool {
        !self.compensator.staged.load(Ordering::Acquire)
    }

    /// See [`Compensator::beyond_range`].
    pub fn beyond_range(&self) -> (u32, f32) {
        self.compensator.beyond_range()
    }

    /// Validates `params` and prepares them, at rest, in the slot the tick does not use; the
    /// next tick switches to it. [`ErrorReply::Busy`] while the tick has not taken the last
    /// set; a refused set changes nothing.
    pub fn stage(&mut self, params: &JointParams) -> Result<(), ErrorReply> {
        if !self.has_room() {
            return Err(ErrorReply::Busy);
        }
        let compensator = self.compensator;
        // `staged` is down, so `active` stays as it is until it is raised below.
        let idle = compensator.slot(compensator.active.load(Ordering::Relaxed) ^ 1);
        // SAFETY: the slot the tick does not use, while `staged` is down: the tick neither
        // reads nor writes it (see `Compensator`'s `Sync`), nor does anything else.
        #[allow(unsafe_code)]
        let idle = unsafe { &mut *idle.get() };
        idle.prepare(params)?;
        compensator.staged.store(true, Ordering::Release);
        Ok(())
    }
}

/// The tick's half of a [`Compensator`]: evaluates the active set.
pub struct Ticker<'a> {
    compensator: &'a Compensator,
}

impl Ticker<'_> {
    /// The slot the last tick used.
    fn active(&self) -> &Installed {
        let compensator = self.compensator;
        // SAFETY: the active slot, which only the tick's half touches (see `Compensator`'s
        // `Sync`); `&self` here, `&mut self` in `tick`, never both.
        #[allow(unsafe_code)]
        unsafe {
            &*compensator.slot(compensator.active.load(Ordering::Relaxed)).get()
        }
    }

    /// Switches to a set the link has staged, if there is one: the one moment the memory is
    /// reset. Every tick does this first (a board's tick at its start, whether it evaluates
    /// the model or not, so that the link can stage the next set; [`Ticker::tick`] too).
    #[inline(always)]
    pub fn activate_staged(&mut self) {
        let compensator = self.compensator;
        // A relaxed load every tick; the fence orders the set's reads only when there is one.
        if compensator.staged.load(Ordering::Relaxed) {
            fence(Ordering::Acquire);
            compensator.active.store(compensator.active.load(Ordering::Relaxed) ^ 1, Ordering::Relaxed);
            compensator.beyond_range.store(0, Ordering::Relaxed);
            compensator.max_excess.store(0, Ordering::Relaxed);
            compensator.staged.store(false, Ordering::Release);
        }
    }

    /// Counts a sample `excess` rad beyond the spring's identified range, if it is > 0. Rare,
    /// so out of the tick's straight path.
    #[cold]
    #[inline(never)]
    fn note_beyond_range(&mut self, excess: f32) {
        // Never NaN: θ was plausible, θ0 and the range finite.
        if excess <= 0.0 {
            return;
        }
        let compensator = self.compensator;
        let count = compensator.beyond_range.load(Ordering::Relaxed);
        compensator.beyond_range.store(count.wrapping_add(1), Ordering::Relaxed);
        if excess.to_bits() > compensator.max_excess.load(Ordering::Relaxed) {
            compensator.max_excess.store(excess.to_bits(), Ordering::Relaxed);
        }
    }

    /// The gear ratio of the set the last tick used: the controller's, each tick.
    pub fn active_gear_ratio(&self) -> Option<f32> {
        let active = self.active();
        active.ready.then_some(active.gear_ratio)
    }

    /// One control tick on the two encoder angles (rad; the input side multi-turn).
    /// Never NaN: without valid parameters, with a deflection that is not finite or beyond
    /// [`MAX_DEFLECTION`], or when the model cannot be evaluated, the compensation is off,
    /// T_ff = K = 0, and the model's memory is left as it was.
    ///
    /// Never inlined: the boards, the controller and `bench/firmware.sh` run one and the same
    /// code, whose instructions per tick the benchmark holds to `crate::budget`.
    #[inline(never)]
    pub fn tick(&mut self, input_angle: f32, output_angle: f32, path: EvalPath) -> Feedforward {
        self.activate_staged();
        let compensator = self.compensator;
        // Built where it is returned: a value made up front was stored to the result on
        // every tick, then overwritten.
        const OFF: Feedforward = Feedforward {
            deflection: 0.0,
            torque: 0.0,
            stiffness: 0.0,
            compensation: Compensation::Off,
            direction: None,
            memory: 0,
        };
        // SAFETY: the active slot, the tick's alone (see `Compensator`'s `Sync`).
        #[allow(unsafe_code)]
        let installed = unsafe { &mut *compensator.slot(compensator.active.load(Ordering::Relaxed)).get() };
        if !installed.ready {
            return OFF;
        }
        let evaluator = &mut installed.evaluator;
        let deflection = input_angle / installed.gear_ratio - output_angle;
        // One comparison on the usual tick: plausible and within the identified range. Outside
        // that window: refused where implausible (NaN too), else counted (beyond the range the
        // spring runs on with its edge's stiffness) and evaluated.
        if !installed.usual.holds(deflection) {
            // One comparison refuses NaN too.
            let plausible = deflection.abs() <= MAX_DEFLECTION;
            if !plausible {
                return OFF;
            }
            self.note_beyond_range(evaluator.excess(deflection));
        }
        // The same state whichever path runs the sample.
        let fast = installed.fast && path == EvalPath::Fast;
        let (evaluation, memory) = evaluator.step_reporting_either::<FastMath, DirectMath>(deflection, fast);
        // Beyond the identified range the spring runs on with its edge's stiffness; such
        // samples are counted (the status reports them).
        // At most TURNING_POINTS or SLIP_ELEMENTS, both 16.
        let (direction, memory) = (memory.direction, memory.depth as u8);
        let Ok(evaluation) = evaluation else {
            return Feedforward { deflection, direction, memory, ..OFF };
        };
        let limit = installed.torque_limit;
        if evaluation.torque.abs() <= limit {
            let (torque, stiffness) = (evaluation.torque, evaluation.stiffness);
            return Feedforward {
                deflection,
                torque,
                stiffness,
                compensation: Compensation::Active,
                direction,
                memory,
            };
        }
        // Saturated: the output no longer changes with θ. (A branch of its own: computed for
        // every tick, the copysign cost a few instructions on the M4F.)
        let torque = limit.copysign(evaluation.torque);
        Feedforward { deflection, torque, stiffness: 0.0, compensation: Compensation::Clamped, direction, memory }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use model_core::memory::slip_grid;
    use model_core::{
        checks::{bouc_wen_set, PAPER_TABLE_2},
        GearModel, Hysteresis, Hysteretic, Kind, Knot, ParamName, SlipElement, Spring, MODEL_VERSION,
    };
    use std::vec::Vec;
    use swg_protocol::{ParamFault, ParamField, SLIP_ELEMENTS};

    const BAND: f32 = 1.0e-6;

    /// The paper's Table 2 on a 1:100 gear, |T_ff| ≤ 40 N·m.
    fn paper() -> JointParams {
        JointParams {
            model_version: MODEL_VERSION,
            model: GearModel::paper(PAPER_TABLE_2.to_f32()),
            gear_ratio: 100.0,
            torque_limit: 40.0,
            direction_band: BAND,
        }
    }

    /// A micro-slip gear of about the paper's size: 6000 N·m/rad of spring, 16 elements of
    /// 200 N·m/rad slipping between 20 µrad and 2 mrad.
    fn slip() -> JointParams {
        let grid: [f32; SLIP_ELEMENTS] = slip_grid(2.0e-5, 2.0e-3).unwrap();
        let elements = grid.map(|slip| SlipElement { slip, stiffness: 200.0 });
        let spring = Spring::polynomial(6000.0, 1.2e10, 0.0);
        JointParams { model: GearModel::micro_slip(0.0, spring, &elements).unwrap(), ..paper() }
    }

    /// A spring on knots, asymmetric, identified over ±1.2 mrad (beyond it, its edge's line), from
    /// a deflection zero of −0.3 mrad: the paper's hysteresis or the micro-slip set's beside it.
    fn knotted(base: JointParams) -> JointParams {
        let knots = [
            Knot { x: -1.2e-3, stiffness: 3.0e4 },
            Knot { x: -0.6e-3, stiffness: 1.8e4 },
            Knot { x: 0.0, stiffness: 1.0e4 },
            Knot { x: 0.6e-3, stiffness: 1.5e4 },
            Knot { x: 1.2e-3, stiffness: 2.5e4 },
        ];
        let spring = Spring::of_knots(&knots, [-1.2e-3, 1.2e-3]).unwrap();
        JointParams { model: GearModel { zero: -3.0e-4, spring, ..base.model }, ..base }
    }

    /// The simulator's Bouc–Wen gear (model-core's check set), with its exponent n.
    fn bouc_wen(n: f32) -> JointParams {
        let mut model = bouc_wen_set().map(|_, v| v as f32);
        if let Hysteresis::BoucWen(term) = &mut model.hysteresis {
            term.shape.n = n;
        }
        JointParams { model, ..paper() }
    }

    /// model-core's Preisach set (its grid of reach 1.4 mrad).
    fn preisach() -> JointParams {
        JointParams { model: model_core::checks::preisach_set().map(|_, v| v as f32), ..paper() }
    }

    /// Every set the tests run: every kind, with the polynomial spring and with knots (Bouc–Wen
    /// with n = 1, integrated in closed form, and with n = 1.5, in Runge–Kutta sub-steps).
    fn sets() -> [JointParams; 9] {
        [
            paper(),
            slip(),
            bouc_wen(1.0),
            bouc_wen(1.5),
            preisach(),
            knotted(paper()),
            knotted(slip()),
            knotted(bouc_wen(1.0)),
            knotted(preisach()),
        ]
    }

    /// model-core's own evaluator of `params`, at rest, in f32 with libm.
    fn reference(params: &JointParams) -> Evaluator<f32> {
        params.model.evaluator(params.direction_band).unwrap()
    }

    /// θ = 0.6·A + 0.15·A·sin φ after a ramp from rest: a held load with an oscillation.
    fn biased(amplitude: f32, n: usize) -> Vec<f32> {
        let ramp = n / 4;
        let bias = 0.6 * amplitude;
        (0..n)
            .map(|i| {
                if i < ramp {
                    bias * i as f32 / ramp as f32
                } else {
                    let phase = core::f32::consts::TAU * 3.0 * (i - ramp) as f32 / (n - ramp) as f32;
                    bias + 0.15 * amplitude * libm::sinf(phase)
                }
            })
            .collect()
    }

    /// θ = A·(0.75·sin φ + 0.25·sin 9φ): minor loops at many levels inside the big swing.
    fn nested(amplitude: f32, n: usize) -> Vec<f32> {
        (0..n)
            .map(|i| {
                let phase = core::f32::consts::TAU * 2.0 * i as f32 / n as f32;
                amplitude * (0.75 * libm::sinf(phase) + 0.25 * libm::sinf(9.0 * phase))
            })
            .collect()
    }

    fn tick_theta(compensator: &mut Compensator, theta: f32, path: EvalPath) -> Feedforward {
        // θ_in = N·θ with θ_out = 0, N = 100: exact for these θ up to f32 rounding of N·θ/N.
        compensator.tick(100.0 * theta, 0.0, path)
    }

    /// S(x) of `spring` in f64, from its definition: the knots' stiffness integrated from 0
    /// (linear between knots, the end knot's beyond them) plus the polynomial, which beyond the
    /// identified range runs on as the line of its stiffness at the range's edge.
    fn spring_torque(spring: &Spring<f32>, x: f64) -> f64 {
        let knots: Vec<(f64, f64)> = spring.knots().iter().map(|k| (f64::from(k.x), f64::from(k.stiffness))).collect();
        let stiffness = |u: f64| match knots.iter().position(|&(at, _)| at > u) {
            None => knots.last().map_or(0.0, |&(_, k)| k),
            Some(0) => knots[0].1,
            Some(j) => {
                let ((a, ka), (b, kb)) = (knots[j - 1], knots[j]);
                ka + (kb - ka) * (u - a) / (b - a)
            }
        };
        // The midpoint rule is exact but at the knots, for a stiffness linear in between.
        let steps = 20_000;
        let knots_part: f64 =
            (0..steps).map(|i| stiffness((i as f64 + 0.5) * x / steps as f64) * x / steps as f64).sum();
        let (c1, c2, c3) = (f64::from(spring.c1), f64::from(spring.c2), f64::from(spring.c3));
        let polynomial = |u: f64| c1 * u + c2 * u.powi(3) + c3 * u.powi(5);
        let slope = |u: f64| c1 + 3.0 * c2 * u.powi(2) + 5.0 * c3 * u.powi(4);
        let [lo, hi] = spring.range.map(f64::from);
        let edge = x.clamp(lo, hi);
        knots_part + polynomial(edge) + slope(edge) * (x - edge)
    }

    /// Beyond the spring's identified range the tick runs on along the line of the edge's
    /// stiffness (the polynomial's runaway would be several times larger here), on both kinds,
    /// from θ0 ≠ 0; the samples beyond are counted with their largest excess, from the set's
    /// activation on.
    #[test]
    fn beyond_the_range_the_spring_runs_on_with_the_edge_stiffness_and_is_counted() {
        let knots = [
            Knot { x: -0.6e-3, stiffness: 3.0e4 },
            Knot { x: 0.0, stiffness: 1.0e4 },
            Knot { x: 0.5e-3, stiffness: 1.5e4 },
        ];
        let spring = Spring { c2: 2.0e9, c3: 1.0e15, ..Spring::of_knots(&knots, [-1.0e-3, 1.2e-3]).unwrap() };
        let zero = -3.0e-4;
        // From rest out to x = 3 mrad, back to x = −2.5 mrad: beyond both edges.
        let path: Vec<f32> = (0..=300)
            .map(|i| 3.0e-3 * i as f32 / 300.0)
            .chain((1..=550).map(|i| 3.0e-3 - 5.5e-3 * i as f32 / 550.0))
            .map(|x| x + zero)
            .collect();
        for base in [paper(), slip()] {
            let set =
                |spring| JointParams { model: GearModel { zero, spring, ..base.model }, torque_limit: 1.0e4, ..base };
            let (mut full, mut bare) = (Compensator::new(), Compensator::new());
            full.stage(set(spring)).unwrap();
            bare.stage(set(Spring::polynomial(0.0, 0.0, 0.0))).unwrap();
            let (mut beyond, mut largest) = (0, 0.0f64);
            for &theta in &path {
                let (with, without) =
                    (tick_theta(&mut full, theta, EvalPath::Fast), tick_theta(&mut bare, theta, EvalPath::Fast));
                assert_eq!(with.compensation, Compensation::Active);
                // The same hysteresis in both: the difference is the spring alone.
                let x = f64::from(with.deflection) - f64::from(zero);
                let expected = spring_torque(&spring, x);
                let got = f64::from(with.torque) - f64::from(without.torque);
                assert!(
                    (got - expected).abs() <= 2.0e-3 + 1.0e-4 * expected.abs(),
                    "{:?} x = {x:e}: S = {got}, expected {expected}",
                    base.model.kind()
                );
                let excess = (x - 1.2e-3).max(-1.0e-3 - x);
                if excess > 0.0 {
                    beyond += 1;
                    largest = largest.max(excess);
                }
            }
            let (count, max_excess) = full.split().0.beyond_range();
            assert!(count.abs_diff(beyond) <= 2, "{count} samples counted, {beyond} beyond");
            assert!(
                (f64::from(max_excess) - largest).abs() < 1.0e-7,
                "largest excess {max_excess}, expected {largest}"
            );
            // A new set starts counting afresh.
            full.stage(set(spring)).unwrap();
            tick_theta(&mut full, zero, EvalPath::Fast);
            assert_eq!(full.split().0.beyond_range(), (0, 0.0));
        }
    }

    #[test]
    fn no_parameters_no_compensation() {
        let mut compensator = Compensator::new();
        let out = compensator.tick(1.0, 0.0, EvalPath::Fast);
        assert_eq!((out.torque, out.stiffness, out.compensation), (0.0, 0.0, Compensation::Off));
    }

    #[test]
    fn deflection_is_input_over_ratio_minus_output() {
        for params in [paper(), slip()] {
            let mut compensator = Compensator::new();
            compensator.stage(params).unwrap();
            let out = compensator.tick(10.0, 0.0995, EvalPath::Direct);
            assert!((out.deflection - 0.5e-3).abs() < 1e-8, "{}", out.deflection);
            assert_eq!(out.compensation, Compensation::Active);
            let expected = reference(&params).step(out.deflection).unwrap();
            assert_eq!((out.torque, out.stiffness), (expected.torque, expected.stiffness));
        }
    }

    /// Both kinds, both paths, through a biased and a nested motion: every tick equals
    /// model-core's evaluator run from rest (bit for bit on the direct path; within the fast
    /// path's error on the fast path), and the memory is reported.
    #[test]
    fn ticks_run_the_stateful_model_from_rest() {
        for params in sets() {
            for motion in [biased(1.0e-3, 2000), nested(1.0e-3, 4000)] {
                for path in [EvalPath::Direct, EvalPath::Fast] {
                    let mut compensator = Compensator::new();
                    compensator.stage(JointParams { torque_limit: 1.0e3, ..params }).unwrap();
                    let mut expected = reference(&params);
                    let mut deepest = 0;
                    for &theta in &motion {
                        let out = tick_theta(&mut compensator, theta, path);
                        let want = expected.step(out.deflection).unwrap();
                        assert_eq!(out.compensation, Compensation::Active);
                        deepest = deepest.max(out.memory);
                        // Bouc–Wen runs the fast path's functions on both paths (model-core's
                        // `step_reporting_either`).
                        let kind = params.model.kind();
                        if (path == EvalPath::Direct && kind != Kind::BoucWen) || kind == Kind::MicroSlip {
                            assert_eq!((out.torque, out.stiffness), (want.torque, want.stiffness));
                        } else {
                            assert!(
                                (out.torque - want.torque).abs() <= 1.0e-4 * (1.0 + want.torque.abs()),
                                "{out:?} {want:?}"
                            );
                            let k_error = (out.stiffness - want.stiffness).abs();
                            assert!(k_error <= 1.0e-3 * (1.0e3 + want.stiffness.abs()), "{out:?} {want:?}");
                        }
                    }
                    // Bouc–Wen keeps z, whatever the motion: no turning points.
                    if params.model.kind() != Kind::BoucWen {
                        assert!(deepest >= 2, "the motion leaves memory behind: {deepest}");
                    }
                }
            }
        }
    }

    /// model-core's evaluator of `params` in f64, at rest.
    fn exact(params: &JointParams) -> Evaluator<f64> {
        params.model.map(|_, v| f64::from(v)).evaluator(f64::from(params.direction_band)).unwrap()
    }

    /// At a reversal the torque turns without a step: no tick moves T_ff by more than the
    /// larger |K| of its two ends times |Δθ|, or, where that is larger, by more than the exact
    /// (f64) model moves over the same Δθ, plus the f32 tolerance (2·10⁻⁵ of the torque scale).
    ///
    /// The second allowance is for the genetic kind's turning points: its branches start with
    /// an infinite slope (z ∝ |cos ωt| ∝ √(distance from the turning point)), and K there is
    /// the capped edge value, so |K|·|Δθ| underestimates the first step of a branch; model-core
    /// proves the exact model continuous (`torque_is_continuous_on_any_motion`), and this test
    /// shows that the joint adds no step of its own. The micro-slip kind is piecewise smooth
    /// with finite K, so it meets the first bound alone (checked). With a reversal band b > 0
    /// (the second pass) the tick that recognises a reversal, θ more than b back from the
    /// extreme, changes branch at the turning point: T_ff moves by the two branches'
    /// difference over about b, as in the exact model, which the second allowance takes in.
    #[test]
    fn the_torque_does_not_step_at_reversals() {
        for band in [0.0, BAND] {
            for params in sets() {
                for motion in [biased(1.0e-3, 2000), nested(1.0e-3, 4000)] {
                    for path in [EvalPath::Direct, EvalPath::Fast] {
                        let mut compensator = Compensator::new();
                        let params = JointParams { torque_limit: 1.0e3, direction_band: band, ..params };
                        compensator.stage(params).unwrap();
                        let mut exact = exact(&params);
                        let mut outs = Vec::new();
                        for &theta in &motion {
                            let out = tick_theta(&mut compensator, theta, path);
                            outs.push((out, exact.step(f64::from(out.deflection)).unwrap()));
                        }
                        let scale = outs.iter().map(|(o, _)| o.torque.abs()).fold(0.0f32, f32::max);
                        let tolerance = 2.0e-5 * f64::from(scale);
                        let mut reversals = 0;
                        for (i, pair) in outs.windows(2).enumerate() {
                            let ((a, exact_a), (b, exact_b)) = (pair[0], pair[1]);
                            if i > 0 && (a.deflection - outs[i - 1].0.deflection) * (b.deflection - a.deflection) < 0.0
                            {
                                reversals += 1;
                            }
                            let step = f64::from((b.torque - a.torque).abs());
                            let by_stiffness = f64::from(a.stiffness.abs().max(b.stiffness.abs()))
                                * f64::from((b.deflection - a.deflection).abs());
                            let exact_step = (exact_b.torque - exact_a.torque).abs();
                            let allowed = match params.model.kind() {
                                Kind::MicroSlip => by_stiffness,
                                Kind::Genetic | Kind::BoucWen | Kind::Preisach => by_stiffness.max(exact_step),
                            } + tolerance;
                            assert!(
                                step <= allowed,
                                "band {band} {path:?} sample {i}: step {step} > {allowed}: {a:?} → {b:?}"
                            );
                        }
                        assert!(reversals >= 6, "{reversals}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_parameter_change_resets_the_memory_when_the_set_is_activated() {
        for (first, second) in [(paper(), slip()), (slip(), paper()), (paper(), paper())] {
            let mut compensator = Compensator::new();
            compensator.stage(first).unwrap();
            let motion = nested(1.0e-3, 1000);
            let mut last = None;
            for &theta in &motion[..700] {
                last = Some(tick_theta(&mut compensator, theta, EvalPath::Fast));
            }
            assert!(last.unwrap().memory > 0, "{last:?}");
            compensator.stage(second).unwrap();
            // Staged, not active: the memory is untouched until the next tick.
            assert!(!compensator.split().0.has_room());
            let theta = motion[700];
            let out = tick_theta(&mut compensator, theta, EvalPath::Direct);
            // That tick starts from rest with the new set: the evaluator's first step.
            let want = reference(&second).step(out.deflection).unwrap();
            assert_eq!((out.torque, out.stiffness), (want.torque, want.stiffness), "{out:?}");
            assert!(out.memory == 0 || second.model.kind() == Kind::MicroSlip, "{out:?}");
            // And the memory builds again from there, as the evaluator's from rest.
            let mut expected = reference(&second);
            expected.step(out.deflection).unwrap();
            for &theta in &motion[701..] {
                let out = tick_theta(&mut compensator, theta, EvalPath::Direct);
                assert_eq!(out.torque, expected.step(out.deflection).unwrap().torque);
            }
        }
    }

    /// One set staged at a time: busy until a tick has switched to it, whether that tick
    /// evaluates the model or not (a board's tick without a sample).
    #[test]
    fn one_set_is_staged_at_a_time() {
        let mut compensator = Compensator::new();
        compensator.stage(paper()).unwrap();
        let motion = nested(1.0e-3, 400);
        for &theta in &motion[..200] {
            tick_theta(&mut compensator, theta, EvalPath::Fast);
        }
        let (mut stager, mut ticker) = compensator.split();
        stager.stage(&slip()).unwrap();
        assert_eq!(stager.stage(&paper()), Err(ErrorReply::Busy));
        assert!(!stager.has_room());
        // The next tick switches to the staged set at its start, from rest.
        let out = ticker.tick(100.0 * motion[200], 0.0, EvalPath::Fast);
        let want = reference(&slip()).step(out.deflection).unwrap();
        assert_eq!((out.torque, out.stiffness), (want.torque, want.stiffness));
        assert!(stager.has_room());
        // A tick that only switches frees the stager too.
        stager.stage(&paper()).unwrap();
        ticker.activate_staged();
        assert!(stager.has_room());
        assert_eq!(ticker.active_gear_ratio(), Some(paper().gear_ratio));
        let out = ticker.tick(100.0 * motion[201], 0.0, EvalPath::Direct);
        assert_eq!(out.torque, reference(&paper()).step(out.deflection).unwrap().torque);
    }

    #[test]
    fn a_refused_set_keeps_the_memory() {
        let mut compensator = Compensator::new();
        compensator.stage(paper()).unwrap();
        let mut twin = compensator.clone();
        let motion = nested(1.0e-3, 1000);
        for &theta in &motion[..500] {
            tick_theta(&mut compensator, theta, EvalPath::Fast);
            tick_theta(&mut twin, theta, EvalPath::Fast);
        }
        let bad = JointParams { model: paper().model.with(ParamName::Alpha, f32::NAN), ..paper() };
        assert!(compensator.stage(bad).is_err());
        for &theta in &motion[500..] {
            assert_eq!(
                tick_theta(&mut compensator, theta, EvalPath::Fast),
                tick_theta(&mut twin, theta, EvalPath::Fast)
            );
        }
    }

    #[test]
    fn torque_is_clamped_and_never_nan() {
        for params in [paper(), slip()] {
            let mut compensator = Compensator::new();
            compensator.stage(params).unwrap();
            for output in [-0.5f32, -1.0e-2, 1.0e-2, 0.5, f32::NAN, f32::INFINITY, 1.0e30, -0.09] {
                for path in [EvalPath::Direct, EvalPath::Fast] {
                    let out = compensator.tick(0.0, output, path);
                    assert!(out.torque.abs() <= params.torque_limit, "{out:?}");
                    assert!(!out.torque.is_nan() && !out.stiffness.is_nan(), "{out:?}");
                }
            }
        }
        // θ = ±3 mrad from rest, past the loops: |T| > 40 N·m, with the sign of θ.
        for params in [paper(), slip()] {
            for (output, limit) in [(-3.0e-3, params.torque_limit), (3.0e-3, -params.torque_limit)] {
                let mut compensator = Compensator::new();
                compensator.stage(params).unwrap();
                let out = compensator.tick(0.0, output, EvalPath::Fast);
                assert_eq!((out.torque, out.stiffness, out.compensation), (limit, 0.0, Compensation::Clamped));
            }
        }
    }

    #[test]
    fn an_encoder_glitch_does_not_disturb_the_memory() {
        for params in [paper(), slip()] {
            let mut steady = Compensator::new();
            steady.stage(params).unwrap();
            let mut glitched = steady.clone();
            let thetas = [0.2e-3f32, 0.6e-3, 1.0e-3, 0.7e-3, 0.1e-3, 0.5e-3];
            for (i, theta) in thetas.into_iter().enumerate() {
                if i == 2 || i == 4 {
                    let out = glitched.tick(0.0, -0.5, EvalPath::Fast);
                    assert_eq!((out.torque, out.compensation), (0.0, Compensation::Off));
                }
                let expected = steady.tick(100.0 * theta, 0.0, EvalPath::Fast);
                assert_eq!(glitched.tick(100.0 * theta, 0.0, EvalPath::Fast), expected);
            }
        }
    }

    #[test]
    fn refused_parameters_leave_the_old_ones_active() {
        let mut compensator = Compensator::new();
        compensator.stage(paper()).unwrap();
        let before = compensator.tick(10.0, 0.0995, EvalPath::Direct);
        let bad = JointParams { model: paper().model.with(ParamName::Alpha, f32::NAN), ..paper() };
        assert_eq!(
            compensator.stage(bad),
            Err(ErrorReply::InvalidParam { field: ParamField::Model(ParamName::Alpha), fault: ParamFault::NotFinite })
        );
        let huge = JointParams {
            model: paper().model.with(ParamName::Alpha, f32::MAX).with(ParamName::Omega, f32::MIN_POSITIVE),
            ..paper()
        };
        // Named by the one parameter whose neutral value (α = 0) would make the set evaluable.
        assert_eq!(
            compensator.stage(huge),
            Err(ErrorReply::InvalidParam { field: ParamField::Model(ParamName::Alpha), fault: ParamFault::OutOfRange })
        );
        let negative = JointParams { model: slip().model.with(ParamName::SlipStiffness(4), -1.0), ..slip() };
        assert_eq!(
            compensator.stage(negative),
            Err(ErrorReply::InvalidParam {
                field: ParamField::Model(ParamName::SlipStiffness(4)),
                fault: ParamFault::OutOfRange
            })
        );
        let overflowing = JointParams { model: slip().model.with(ParamName::C3, f32::MAX), ..slip() };
        assert_eq!(
            compensator.stage(overflowing),
            Err(ErrorReply::InvalidParam { field: ParamField::Model(ParamName::C3), fault: ParamFault::OutOfRange })
        );
        // Nothing staged: the old set stays.
        assert!(compensator.split().0.has_room());
        assert_eq!(compensator.tick(10.0, 0.0995, EvalPath::Direct).torque, before.torque);
    }

    /// Every parameter of both kinds at a 1e38-class value (ω at 1e-38, where it overflows):
    /// refused with the parameter named, the old set and its memory active. Before the range
    /// check (model-core's `range`, through `JointParams::validate`) c1, c2 < 1.1e38, c3 = 1e38,
    /// β, each k_i and the slip range were accepted, and every tick was then off.
    /// Every parameter name of `model`'s kind, in order.
    fn names(model: &GearModel<f32>) -> Vec<ParamName> {
        let mut names = Vec::new();
        model.map(|name, value| {
            names.push(name);
            value
        });
        names
    }

    #[test]
    fn a_set_that_overflows_anywhere_in_range_is_refused() {
        let mut cases: Vec<(JointParams, ParamField)> = Vec::new();
        for base in sets() {
            for name in names(&base.model) {
                let huge = match name {
                    ParamName::Omega => 1.0e-38,
                    // A wider grid only spreads the relays thinner; a narrow one steepens them.
                    ParamName::PreisachReach => 1.0e-38,
                    // A larger β, γ or n only narrows Bouc–Wen's z: nothing overflows (model-core's
                    // range tests); A is tested below.
                    ParamName::BoucWenA | ParamName::BoucWenBeta | ParamName::BoucWenGamma | ParamName::BoucWenN => {
                        continue
                    }
                    // A knot's or an element's x out of order names the next one (the checks of
                    // the spring and the kind); the last element's is beyond the travel.
                    ParamName::Knot(_) => continue,
                    ParamName::Slip(i) if usize::from(i) + 1 < base.model.slip_elements().len() => continue,
                    ParamName::RangeMin => -1.0e38,
                    _ => 1.0e38,
                };
                cases.push((JointParams { model: base.model.with(name, huge), ..base }, ParamField::Model(name)));
            }
        }
        // A scales z_max = A/(β + γ) with k_h: k_h, whose 0 switches the hysteresis off, is named.
        let bouc_wen = bouc_wen(1.0);
        cases.push((
            JointParams { model: bouc_wen.model.with(ParamName::BoucWenA, 1.0e38), ..bouc_wen },
            ParamField::Model(ParamName::HysteresisStiffness),
        ));
        for (bad, field) in cases {
            let mut compensator = Compensator::new();
            compensator.stage(paper()).unwrap();
            let mut twin = compensator.clone();
            let motion = nested(1.0e-3, 400);
            for &theta in &motion[..200] {
                tick_theta(&mut compensator, theta, EvalPath::Fast);
                tick_theta(&mut twin, theta, EvalPath::Fast);
            }
            let refused = Err(ErrorReply::InvalidParam { field, fault: ParamFault::OutOfRange });
            assert_eq!(compensator.stage(bad), refused, "{bad:?}");
            assert!(compensator.split().0.has_room(), "nothing staged");
            for &theta in &motion[200..] {
                let out = tick_theta(&mut compensator, theta, EvalPath::Fast);
                assert_eq!(out, tick_theta(&mut twin, theta, EvalPath::Fast));
                assert_eq!(out.compensation, Compensation::Active);
            }
        }
    }

    /// θ = ±MAX_DEFLECTION·(0.75·sin φ + 0.25·sin 9φ) after a ramp: the largest loop the joint
    /// sees, and nested ones inside it, in both directions.
    fn full_range(n: usize) -> Vec<f32> {
        let mut motion = nested(MAX_DEFLECTION, n);
        motion.extend(nested(MAX_DEFLECTION, n).iter().map(|t| -t));
        motion.extend((0..=n).map(|i| MAX_DEFLECTION * (2.0 * i as f32 / n as f32 - 1.0)));
        motion.extend((0..=n).map(|i| MAX_DEFLECTION * (1.0 - 2.0 * i as f32 / n as f32)));
        motion
    }

    /// The other side of the check: each parameter pushed by decades to the largest value it
    /// accepts, and that set evaluated on both paths over the whole range (the largest loop, the
    /// ends ±MAX_DEFLECTION, nested loops): no tick is off.
    #[test]
    fn the_largest_accepted_sets_evaluate_over_the_whole_range() {
        let evaluate = |params: JointParams| {
            for path in [EvalPath::Direct, EvalPath::Fast] {
                let mut compensator = Compensator::new();
                compensator.stage(params).unwrap_or_else(|e| panic!("{params:?}: {e:?}"));
                for theta in full_range(400) {
                    let out = compensator.tick(100.0 * theta, 0.0, path);
                    assert_ne!(out.compensation, Compensation::Off, "{params:?} {path:?} {theta}: {out:?}");
                }
            }
        };
        for base in sets() {
            let limit = JointParams { torque_limit: f32::MAX, ..base };
            for name in names(&base.model) {
                let push = |value: f32, scale: f32| match name {
                    ParamName::Omega => value / scale,
                    // From a slope of a real gear's size where the reference set has none.
                    ParamName::C3 if value == 0.0 => 1.0e10 * scale,
                    _ => value * scale,
                };

                let mut last = None;
                for decade in 0..90 {
                    let scale = libm::powf(10.0, decade as f32);
                    let model = limit.model.map(|each, value| if each == name { push(value, scale) } else { value });
                    let params = JointParams { model, ..limit };
                    if params.validate().is_err() {
                        break;
                    }
                    last = Some(params);
                }
                evaluate(last.unwrap());
            }
        }
    }

    #[test]
    fn a_staged_set_applies_whole_at_the_next_tick() {
        let mut compensator = Compensator::new();
        compensator.stage(paper()).unwrap();
        compensator.tick(10.0, 0.0995, EvalPath::Fast);
        let c1 = PAPER_TABLE_2.c1 as f32;
        let stiffer = JointParams { model: paper().model.with(ParamName::C1, 2.0 * c1), gear_ratio: 50.0, ..paper() };
        compensator.stage(stiffer).unwrap();
        assert!(!compensator.split().0.has_room(), "staged for the next tick");
        // Same deflection as before only under the new ratio: both fields changed together.
        let out = compensator.tick(5.0, 0.0995, EvalPath::Direct);
        assert!((out.deflection - 0.5e-3).abs() < 1e-8);
        assert_eq!(out.torque, reference(&stiffer).step(out.deflection).unwrap().torque);
    }
}
