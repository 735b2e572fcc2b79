//! `swg-host push`: send a parameter file to a joint, verify it, store it in its flash.
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use std::time::Duration;
use swg_host::link::push::{joint_params, push, JointSettings};
use swg_host::link::Link;
use swg_host::report::params::read_model;

#[derive(Args)]
pub struct PushArgs {
    /// Parameter file of either model kind (JSON with `model` and `params`, as `swg-host fit
    /// --out` writes): the genetic model or the micro-slip model.
    #[arg(value_name = "PARAMS.json")]
    params: PathBuf,
    #[command(flatten)]
    port: PortOptions,
    /// Gear reduction ratio N of the joint: deflection θ = θ_in/N − θ_out.
    #[arg(long, value_name = "N")]
    ratio: f64,
    /// Limit of the feed-forward torque, N·m.
    #[arg(long, default_value_t = 30.0, value_name = "NM")]
    torque_limit: f64,
    /// How far θ must move back from an extreme before the genetic model records a turning
    /// point, rad; set it above the encoders' noise at the output.
    #[arg(long, default_value_t = 2.0e-6, value_name = "RAD")]
    direction_band: f64,
}

/// Where the joint is.
#[derive(Args, Clone, Debug)]
pub struct PortOptions {
    /// Serial device (/dev/ttyACM0, COM3) or tcp://HOST:PORT.
    #[arg(long, value_name = "PORT")]
    pub port: String,
    /// How long to wait for each response, ms.
    #[arg(long, default_value_t = 2000, value_name = "MS")]
    pub timeout_ms: u64,
}

impl PortOptions {
    pub fn open(&self) -> Result<Link> {
        Ok(Link::open(&self.port, Duration::from_millis(self.timeout_ms))?)
    }
}

pub fn run(args: PushArgs) -> Result<()> {
    let model = read_model(&args.params)?;
    let settings =
        JointSettings { gear_ratio: args.ratio, torque_limit: args.torque_limit, direction_band: args.direction_band };
    let joint = joint_params(&model, &settings)?;
    let mut link = args.port.open()?;
    let report = push(&mut link, &joint).with_context(|| format!("push to {} failed", args.port.port))?;
    let device = report.device;
    let replaced = match report.previous {
        Some(previous) => previous.model.to_string(),
        None => "nothing (the device had no parameters)".to_string(),
    };
    super::print_report(&format!(
        "device on {}: firmware {}, protocol {}, model {}\nreplaced: {replaced}\nwrote and read back: {}, ratio {}, \
         torque limit {} N·m, direction band {:e} rad\ncommitted to flash as record {} in {:.1} ms (version check, \
         write, read-back, commit)\n",
        args.port.port,
        device.firmware_version,
        device.protocol_version,
        device.model_version,
        joint.model,
        joint.gear_ratio,
        joint.torque_limit,
        joint.direction_band,
        report.sequence,
        report.elapsed.as_secs_f64() * 1e3
    ))
}
