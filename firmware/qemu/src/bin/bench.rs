//! Instructions per T_ff + K evaluation, per compensator tick, and per tick of the torque
//! controller with its evaluator (`Controller::tick` in model mode) on the emulated Cortex-M4F,
//! against the budgets of `swg_joint::budget`: exits with status 1 when a figure exceeds its
//! budget. Run under `qemu-system-arm -icount shift=0`: one instruction per ns of virtual time,
//! SysTick at 25 MHz, so one SysTick tick is 40 instructions, exactly repeatable
//! (bench/firmware.sh).
#![no_std]
#![no_main]

use core::hint::black_box;
use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::entry;
use cortex_m_semihosting::hprintln;
use model_core::bouc_wen::BoucWen;
use model_core::checks::{bouc_wen_set, micro_slip_set, preisach_set, SEED_TABLE_FIT};
use model_core::{Direction, Model};
use model_core::{Hysteresis, Knot, Spring};
use swg_joint::budget::{self, CONTROL_TICK_INSTRUCTIONS};
use swg_joint::handoff::{Command, Handoff, TickTiming};
use swg_joint::{Compensator, Controller, FastModel, Joint, NoDrive, Readings, TickStart};
use swg_protocol::experiment::BATCH_SAMPLES;
use swg_protocol::plan::{Channel, Limits, Plan, Segment};
use swg_protocol::{
    ControlMode, ControllerConfig, EvalPath, GearModel, JointParams, MODEL_VERSION, SLIP_ELEMENTS, TURNING_POINTS,
};

const INSTRUCTIONS_PER_TICK: u32 = 40;
const RUNS: u32 = 2000;
/// Runs of each tick along a motion: a SysTick tick is 40 instructions, so one tick's figure
/// is exact to ±2·40/REPEATS (two measurements, each to one SysTick tick).
const REPEATS: u32 = 200;
/// Ticks of the nested motion: two cycles, as the compensator's tests run it.
const NESTED_TICKS: u32 = 4000;
const AMPLITUDE: f32 = 1.168e-3;
/// Every benchmark set's deflection zero θ0, rad: the motions are x = θ − θ0, from rest.
const ZERO: f32 = 1.0e-4;
/// The nested motion's largest deflection per tick, A·(0.75 + 0.25·9)·2π·2/[`NESTED_TICKS`]
/// = 11 µrad: 0.22 rad/s at 20 kHz, a full-amplitude torque swing at 30 Hz. A tick whose cost
/// grows with the travel (Bouc–Wen's sub-steps for n ≠ 1) is measured at a gear's speed, not
/// at the hundred times of a zigzag of ten ticks a leg.
const TOP_TRAVEL_PER_TICK: f32 = AMPLITUDE * 3.0 * core::f32::consts::TAU * 2.0 / NESTED_TICKS as f32;
/// The Bouc–Wen gears' largest hysteretic deflection, rad.
const BOUC_WEN_Z_MAX: f32 = 0.4e-3;
const RATIO: f32 = 100.0;

/// SysTick ticks taken by `body` (a 24-bit down-counter; runs stay below its period).
fn ticks(body: impl FnOnce()) -> u32 {
    let start = SYST::get_current();
    body();
    let end = SYST::get_current();
    start.wrapping_sub(end) & 0x00FF_FFFF
}

/// Deflection of run `i`: points spread over the loop, both branches.
fn point(i: u32) -> (f32, Direction) {
    let x = ((i * 37) % 200) as f32 / 100.0 - 1.0;
    let direction = if i % 2 == 0 { Direction::Rising } else { Direction::Falling };
    (x * AMPLITUDE * 0.999, direction)
}

fn per_run(total_ticks: u32, baseline_ticks: u32, runs: u32) -> f32 {
    (total_ticks.saturating_sub(baseline_ticks) * INSTRUCTIONS_PER_TICK) as f32 / runs as f32
}

/// Instructions of one `step` of `state` at θ: the step run [`REPEATS`] times, each on a copy
/// of `state` made afresh, less the copies alone (written exactly as in the timed loop: a copy
/// passed by value to `black_box` is a second copy the timed loop does not make, and
/// subtracting it undercounted the tick by about one state copy).
fn one_step<S: Clone>(state: &S, theta: f32, step: &impl Fn(&mut S, f32)) -> f32 {
    let copies = ticks(|| {
        for _ in 0..REPEATS {
            let copy = black_box(state).clone();
            black_box(&copy);
        }
    });
    let stepped = ticks(|| {
        for _ in 0..REPEATS {
            let mut copy = black_box(state).clone();
            step(&mut copy, black_box(theta));
            black_box(&copy);
        }
    });
    per_run(stepped, copies, REPEATS)
}

/// Per-tick instructions along a motion: the largest and the mean.
#[derive(Clone, Copy, Debug)]
struct Figures {
    max: f32,
    mean: f32,
    /// The tick (0-based) of the largest.
    worst: usize,
}

/// Every tick of `motion` from `state`, each measured on its own ([`one_step`]) from the state
/// the ticks before it left.
fn every_tick<S: Clone>(mut state: S, motion: impl Iterator<Item = f32>, step: impl Fn(&mut S, f32)) -> Figures {
    let (mut max, mut sum, mut worst, mut count) = (0.0f32, 0.0f32, 0, 0);
    for (i, theta) in motion.enumerate() {
        let instructions = one_step(&state, theta, &step);
        if instructions > max {
            (max, worst) = (instructions, i);
        }
        sum += instructions;
        count += 1;
        step(&mut state, theta);
    }
    Figures { max, mean: sum / count.max(1) as f32, worst }
}

/// θ along a nested motion from rest, A·(0.75·sin φ + 0.25·sin 9φ) over two cycles in
/// `ticks` ticks: minor loops at many levels inside the big swing (the compensator's tests'
/// motion).
fn nested_motion(ticks: u32) -> impl Iterator<Item = f32> + Clone {
    (0..ticks).map(move |i| {
        let phase = core::f32::consts::TAU * 2.0 * i as f32 / ticks as f32;
        AMPLITUDE * (0.75 * libm::sinf(phase) + 0.25 * libm::sinf(9.0 * phase))
    })
}

/// A motion from rest that fills the genetic model's stack: a zigzag of shrinking excursions
/// about 0.2·A, each reversing inside the last, to each of its [`TURNING_POINTS`]` + 2` turning
/// points (the last two find the stack full and retrace); then out to 1.05·A, which wipes every
/// stored point out. It moves at the nested motion's top speed, [`TOP_TRAVEL_PER_TICK`].
fn deep_motion() -> impl Iterator<Item = f32> + Clone {
    deep_legs(TURNING_POINTS as u32 + 3)
}

/// The first `legs` legs of [`deep_motion`].
fn deep_legs(legs: u32) -> impl Iterator<Item = f32> + Clone {
    let target = |k: u32| {
        let size = AMPLITUDE * (1.0 - 0.05 * k as f32);
        if k % 2 == 0 {
            size
        } else {
            -0.6 * size
        }
    };
    let last = TURNING_POINTS as u32 + 2;
    (0..legs.min(last + 1)).flat_map(move |k| {
        let from = if k == 0 { 0.0 } else { target(k - 1) };
        let to = if k == last { 1.05 * AMPLITUDE } else { target(k) };
        let ticks = libm::ceilf(libm::fabsf(to - from) / TOP_TRAVEL_PER_TICK) as u32;
        (1..=ticks).map(move |s| from + (to - from) * s as f32 / ticks as f32)
    })
}

/// The motor encoder's reading at deflection θ0 + `x` (the output's at 0).
fn reading(x: f32) -> f32 {
    (ZERO + x) * RATIO
}

/// A tick at deflection θ0 + `x`.
fn compensator_step(compensator: &mut Compensator, x: f32) {
    black_box(compensator.tick(reading(x), 0.0, EvalPath::Fast));
}

/// A controller tick at deflection θ0 + `x`.
fn controller_step(state: &mut (Controller, Compensator), x: f32) {
    let (controller, compensator) = state;
    black_box(controller.tick(&mut compensator.ticker(), reading(x), 0.0, black_box(12.5)));
}

/// Mean instructions per tick along `motion`, consecutive ticks from rest with no copies (a
/// check on [`every_tick`]'s mean): the compensator alone, and the controller with it.
fn consecutive(params: JointParams, motion: impl Iterator<Item = f32> + Clone) -> (f32, f32) {
    let count = motion.clone().count() as u32;
    let baseline = ticks(|| {
        for theta in motion.clone() {
            black_box(reading(black_box(theta)));
        }
    });
    let mut compensator = installed(params);
    let alone = ticks(|| {
        for theta in motion.clone() {
            compensator_step(&mut compensator, black_box(theta));
        }
    });
    let mut state = controlling(installed(params), 0.0);
    let controlled = ticks(|| {
        for theta in motion.clone() {
            controller_step(&mut state, black_box(theta));
        }
    });
    (per_run(alone, baseline, count), per_run(controlled, baseline, count))
}

fn installed(params: JointParams) -> Compensator {
    let mut compensator = Compensator::new();
    if compensator.stage(params).is_err() {
        swg_firmware_qemu::exit(false)
    }
    compensator
}

/// The controller in model mode, as `hil` configures it.
fn controller_config() -> ControllerConfig {
    ControllerConfig {
        mode: ControlMode::Model,
        kp: 0.06,
        ki: 6.0,
        integral_deadband: 0.1,
        damping: 0.015,
        torsion_damping: 0.03,
        stiffness: 9000.0,
        command_limit: 1.0,
        period: 1.0e-3,
    }
}

/// The controller in model mode after a first tick at θ = `last`, with `compensator`.
fn controlling(compensator: Compensator, last: f32) -> (Controller, Compensator) {
    let mut controller = Controller::new();
    if controller.configure(controller_config()).is_err() {
        swg_firmware_qemu::exit(false)
    }
    let mut state = (controller, compensator);
    controller_step(&mut state, last);
    state
}

/// Runs of [`streaming`], each from boot: a tick's figure is the mean of its runs.
const STREAM_RUNS: u32 = 32;
/// Ticks of [`streaming`]'s plan, at most.
const STREAM_TICKS: usize = 1024;

/// Every tick of the board's own tick (`Joint::own_tick`: the controller in model mode with its
/// evaluator, and an experiment playing, checking and recording each tick) along a deflection
/// plan of a sine, a ramp and a hold with dither, the joint following it exactly; the link
/// fetches a batch after every [`BATCH_SAMPLES`] ticks (between ticks, not counted). Each tick
/// is timed alone, in each of [`STREAM_RUNS`] runs from boot. Without `experiment`, the same
/// ticks along the same motion with no experiment started: its share is the difference.
fn streaming(params: JointParams, baseline: u32, experiment: bool) -> Figures {
    let a = 0.8 * AMPLITUDE;
    let segments = [
        Segment::Sine { amplitude: a, frequency_hz: 5.0, cycles: 3 },
        Segment::Ramp { to: 0.5 * a, seconds: 0.05 },
        Segment::Hold { seconds: 0.2, dither_amplitude: 0.05 * a, dither_hz: 25.0 },
        Segment::Ramp { to: 0.0, seconds: 0.05 },
    ];
    let limits = Limits { torque_nm: 100.0, deflection_rad: 2.0 * AMPLITUDE };
    let Ok(plan) = Plan::new(Channel::Deflection, limits, 1000.0, &segments) else { swg_firmware_qemu::exit(false) };
    let mut sums = [0u32; STREAM_TICKS];
    let start = TickStart { latency: 0, now: 0 };
    for _ in 0..STREAM_RUNS {
        let mut handoff = Handoff::new(TickTiming::UNTIMED);
        let (mut link, mut tick) = handoff.split();
        let (mut joint, mut drive) = (Joint::new(), NoDrive);
        let rest =
            Readings { input_angle: reading(0.0), output_angle: 0.0, torque: Some(0.0), temperature: Some(30.0) };
        if link.stage(&params).is_err() || link.post(Command::Configure(controller_config())).is_err() {
            swg_firmware_qemu::exit(false)
        }
        joint.own_tick(&mut tick, start, Ok::<_, core::convert::Infallible>(rest), &mut drive);
        if experiment && link.experiment().start(&plan).is_err() {
            swg_firmware_qemu::exit(false)
        }
        for (k, setpoint) in plan.player::<f32>().enumerate().take(STREAM_TICKS) {
            let theta = setpoint.value;
            let readings = Readings { input_angle: reading(theta), torque: Some(9.0e3 * theta), ..rest };
            let taken = ticks(|| {
                joint.own_tick(&mut tick, start, Ok::<_, core::convert::Infallible>(black_box(readings)), &mut drive)
            });
            if let Some(sum) = sums.get_mut(k) {
                *sum += taken.saturating_sub(baseline);
            }
            if k % BATCH_SAMPLES == BATCH_SAMPLES - 1 {
                black_box(link.experiment().fetch(0, 0));
            }
        }
    }
    let count = (plan.ticks() as usize).min(STREAM_TICKS);
    let per_tick = |sum: u32| (sum * INSTRUCTIONS_PER_TICK) as f32 / STREAM_RUNS as f32;
    let (mut max, mut worst, mut total) = (0.0f32, 0, 0.0f32);
    for (k, &sum) in sums.iter().enumerate().take(count) {
        let figure = per_tick(sum);
        if figure > max {
            (max, worst) = (figure, k);
        }
        total += figure;
    }
    Figures { max, mean: total / count.max(1) as f32, worst }
}

/// The compensator after [`deep_motion`] up to its last turning point (the stack full), and
/// that θ.
fn full_stack(params: JointParams) -> (Compensator, f32) {
    let mut compensator = installed(params);
    let mut theta = 0.0;
    for t in deep_legs(TURNING_POINTS as u32 + 2) {
        compensator_step(&mut compensator, t);
        theta = t;
    }
    (compensator, theta)
}

/// The instruction figures checked against their budgets: each one over is printed.
struct Budgets {
    checked: u32,
    over: u32,
}

impl Budgets {
    /// `figure` (instructions per tick) of `what` against `budget`.
    fn check(&mut self, what: core::fmt::Arguments, figure: f32, budget: u32) {
        self.checked += 1;
        if figure > budget as f32 {
            self.over += 1;
            hprintln!("OVER BUDGET: {}: {:.1} instructions per tick, budget {}", what, figure, budget);
        }
    }
}

#[entry]
fn main() -> ! {
    let Some(mut core) = cortex_m::Peripherals::take() else { swg_firmware_qemu::exit(false) };
    core.SYST.set_clock_source(SystClkSource::Core);
    core.SYST.set_reload(0x00FF_FFFF);
    core.SYST.clear_current();
    core.SYST.enable_counter();
    // For bench/firmware.sh, which checks the build's size against them.
    hprintln!("budgets of the QEMU build: flash {} B, RAM {} B", budget::FLASH_BYTES, budget::RAM_BYTES);

    let params = SEED_TABLE_FIT.to_f32();
    let (Ok(model), Ok(fast)) = (Model::new(params), FastModel::new(&params)) else { swg_firmware_qemu::exit(false) };
    // The sets a fit writes: θ0 off zero and a spring of the most knots (17, over ±1.2·A, its
    // stiffness rising away from 0, the + side softer), then the kind's hysteresis.
    let mut knots = [Knot::default(); 17];
    for (j, knot) in knots.iter_mut().enumerate() {
        let u = j as f32 / 8.0 - 1.0;
        let stiffness = 9.0e3 * (1.0 + 2.0 * u * u) * if u > 0.0 { 0.8 } else { 1.0 };
        *knot = Knot { x: 1.2 * AMPLITUDE * u, stiffness };
    }
    let Ok(spring) = Spring::of_knots(&knots, [-1.2 * AMPLITUDE, 1.2 * AMPLITUDE]) else {
        swg_firmware_qemu::exit(false)
    };
    let hysteresis = GearModel::paper(model_core::Params { c1: 0.0, c2: 0.0, c3: 0.0, ..params });
    let genetic = JointParams {
        model_version: MODEL_VERSION,
        model: GearModel { zero: ZERO, spring, ..hysteresis },
        gear_ratio: RATIO,
        torque_limit: 100.0,
        direction_band: 1.0e-6,
    };
    let Ok(slip_set) = micro_slip_set() else { swg_firmware_qemu::exit(false) };
    let slip_hysteresis = slip_set.map(|_, v| v as f32);
    let slip = JointParams { model: GearModel { zero: ZERO, spring, ..slip_hysteresis }, ..genetic };
    // The simulator's Bouc–Wen gear (z_max = 0.4 mrad, k_h = 1350 N·m/rad) with n = 1 (closed
    // form) and n = 1.5 (Taylor sub-steps), β = γ set for the same z_max.
    let bouc_wen = |n: f32| {
        let mut model = GearModel { zero: ZERO, spring, ..bouc_wen_set().map(|_, v| v as f32) };
        if let Hysteresis::BoucWen(term) = &mut model.hysteresis {
            let half_sum = 0.5 * term.shape.a / libm::powf(BOUC_WEN_Z_MAX, n);
            term.shape = BoucWen { n, beta: half_sum, gamma: half_sum, ..term.shape };
        }
        JointParams { model, ..genetic }
    };
    // model-core's Preisach set: its grid of reach 1.4 mrad holds every motion here.
    let preisach =
        JointParams { model: GearModel { zero: ZERO, spring, ..preisach_set().map(|_, v| v as f32) }, ..genetic };
    let kinds = [
        ("genetic", genetic),
        ("micro-slip", slip),
        ("bouc-wen n=1", bouc_wen(1.0)),
        ("bouc-wen n=1.5", bouc_wen(1.5)),
        ("preisach", preisach),
    ];

    // The loop and the black boxes alone, subtracted from every measurement.
    let baseline = ticks(|| {
        for i in 0..RUNS {
            black_box(point(black_box(i)));
        }
    });
    let direct = ticks(|| {
        for i in 0..RUNS {
            let (theta, direction) = point(black_box(i));
            let result = model.at_amplitude(black_box(AMPLITUDE)).and_then(|lp| lp.evaluate(theta, direction));
            black_box(result.ok());
        }
    });
    let fast_path = ticks(|| {
        for i in 0..RUNS {
            let (theta, direction) = point(black_box(i));
            black_box(fast.evaluate(theta, direction, black_box(AMPLITUDE)));
        }
    });
    hprintln!(
        "symmetric loop, one T_ff + K evaluation: direct (model-core f32, libm) {}, fast path {}",
        per_run(direct, baseline, RUNS),
        per_run(fast_path, baseline, RUNS)
    );

    let mut budgets = Budgets { checked: 0, over: 0 };
    hprintln!(
        "== instructions per tick on every tick of a motion from rest, each measured alone ({} runs from a copy of the state before it; fast path)",
        REPEATS
    );
    hprintln!(
        "   nested: A·(0.75·sin φ + 0.25·sin 9φ), two cycles in {} ticks (the compensator tests' motion)",
        NESTED_TICKS
    );
    hprintln!(
        "   deep: a zigzag of shrinking excursions that fills the {} turning points, then out to 1.05·A ({} ticks)",
        TURNING_POINTS,
        deep_motion().count()
    );
    hprintln!("kind            motion   evaluator max (tick)   mean    controller + evaluator max (tick)   mean");
    for (kind, params) in kinds {
        let evaluator_budget = budget::evaluator_tick_instructions(&params.model);
        for motion in ["nested", "deep"] {
            let (evaluator, controlled) = if motion == "nested" {
                (
                    every_tick(installed(params), nested_motion(NESTED_TICKS), compensator_step),
                    every_tick(controlling(installed(params), 0.0), nested_motion(NESTED_TICKS), controller_step),
                )
            } else {
                (
                    every_tick(installed(params), deep_motion(), compensator_step),
                    every_tick(controlling(installed(params), 0.0), deep_motion(), controller_step),
                )
            };
            hprintln!(
                "{:<15} {:<8} {:>6.1} ({:>4})          {:>6.1}  {:>6.1} ({:>4})                       {:>6.1}",
                kind,
                motion,
                evaluator.max,
                evaluator.worst,
                evaluator.mean,
                controlled.max,
                controlled.worst,
                controlled.mean
            );
            budgets.check(format_args!("{} evaluator, {} motion, max", kind, motion), evaluator.max, evaluator_budget);
            budgets.check(
                format_args!("{} evaluator, {} motion, mean", kind, motion),
                evaluator.mean,
                evaluator_budget,
            );
            let control = CONTROL_TICK_INSTRUCTIONS;
            budgets.check(
                format_args!("{} controller + evaluator, {} motion, max", kind, motion),
                controlled.max,
                control,
            );
            budgets.check(
                format_args!("{} controller + evaluator, {} motion, mean", kind, motion),
                controlled.mean,
                control,
            );
        }
    }
    for (kind, params) in kinds {
        let (alone, controlled) = consecutive(params, nested_motion(NESTED_TICKS));
        hprintln!(
            "{} along the nested motion from consecutive ticks (no copies), mean: evaluator {:.1}, controller + evaluator {:.1}",
            kind,
            alone,
            controlled
        );
    }

    // Chosen ticks from a full stack (16 turning points) for each kind: a tick onward on the
    // innermost branch, a tick that reverses (the stack being full, it retraces), and a tick
    // that wipes out every stored turning point (θ beyond the outermost); the genetic kind on
    // both paths (the direct path, for replays, has no budget).
    hprintln!("== chosen ticks from a full stack: on the branch, reversal, beyond every stored point");
    let (full, last) = full_stack(genetic);
    let depth = full.clone().tick(reading(last * 1.001), 0.0, EvalPath::Fast).memory;
    let chosen = [last * 1.001, last - 0.05 * AMPLITUDE * last.signum(), 1.05 * AMPLITUDE];
    let genetic_budget = budget::evaluator_tick_instructions(&genetic.model);
    for path in [EvalPath::Fast, EvalPath::Direct] {
        let ticks = chosen.map(|theta| {
            one_step(&full, theta, &|c: &mut Compensator, t| {
                black_box(c.tick(reading(t), 0.0, path));
            })
        });
        hprintln!(
            "genetic ({} turning points stored), {:?} path: {:.1} / {:.1} / {:.1}",
            depth,
            path,
            ticks[0],
            ticks[1],
            ticks[2]
        );
        if path == EvalPath::Fast {
            for (tick, figure) in ticks.into_iter().enumerate() {
                budgets.check(format_args!("genetic evaluator, chosen tick {}", tick), figure, genetic_budget);
            }
        }
    }
    let (slipping, slip_last) = full_stack(slip);
    let slip_chosen = [slip_last * 1.001, slip_last - 0.05 * AMPLITUDE * slip_last.signum(), 1.05 * AMPLITUDE];
    let ticks = slip_chosen.map(|theta| one_step(&slipping, theta, &compensator_step));
    hprintln!("micro-slip ({} elements): {:.1} / {:.1} / {:.1}", SLIP_ELEMENTS, ticks[0], ticks[1], ticks[2]);
    for (tick, figure) in ticks.into_iter().enumerate() {
        budgets.check(
            format_args!("micro-slip evaluator, chosen tick {}", tick),
            figure,
            budget::evaluator_tick_instructions(&slip.model),
        );
    }
    for (kind, state, chosen) in
        [("genetic", controlling(full, last), chosen), ("micro-slip", controlling(slipping, slip_last), slip_chosen)]
    {
        let ticks = chosen.map(|theta| one_step(&state, theta, &controller_step));
        hprintln!("controller + evaluator (model mode), {}: {:.1} / {:.1} / {:.1}", kind, ticks[0], ticks[1], ticks[2]);
        for (tick, figure) in ticks.into_iter().enumerate() {
            budgets.check(
                format_args!("{} controller + evaluator, chosen tick {}", kind, tick),
                figure,
                CONTROL_TICK_INSTRUCTIONS,
            );
        }
    }
    // The whole own tick while an experiment streams (the board's timer tick: its bookkeeping,
    // the experiment, the controller and evaluator), each kind.
    hprintln!("== the board's own tick while an experiment plays and records (model mode, {} runs each)", STREAM_RUNS);
    let single = crate::ticks(|| {});
    for (kind, params) in kinds {
        let (with, without) = (streaming(params, single, true), streaming(params, single, false));
        hprintln!(
            "{} own tick, streaming: max {:.1} (tick {}), mean {:.1}; the same ticks without an experiment: max {:.1}, mean {:.1}",
            kind,
            with.max,
            with.worst,
            with.mean,
            without.max,
            without.mean
        );
        let budget = budget::STREAMING_TICK_INSTRUCTIONS;
        budgets.check(format_args!("{} own tick streaming, max", kind), with.max, budget);
        budgets.check(format_args!("{} own tick streaming, mean", kind), with.mean, budget);
    }
    hprintln!(
        "budgets (firmware/joint/src/budget.rs): evaluator {} (genetic) / {} (micro-slip) / {} (bouc-wen) / {} (preisach), controller + evaluator {}, own tick streaming {}: {} of {} instruction figures over",
        genetic_budget,
        budget::evaluator_tick_instructions(&slip.model),
        budget::evaluator_tick_instructions(&bouc_wen(1.0).model),
        budget::evaluator_tick_instructions(&preisach.model),
        CONTROL_TICK_INSTRUCTIONS,
        budget::STREAMING_TICK_INSTRUCTIONS,
        budgets.over,
        budgets.checked
    );
    swg_firmware_qemu::exit(budgets.over == 0)
}
