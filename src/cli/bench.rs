//! `pegtwin bench`: the speed of a campaign's pieces on this machine.

use clap::Args;
use pegtwin::campaign::bench::{BenchOptions, campaign_rows, run, table};
use pegtwin::campaign::scenario::Scenario;
use pegtwin::error::{Error, Result};

#[derive(Args)]
pub struct BenchArgs {
    /// Physics steps measured on the cross's arm scene (the gear's runs a tenth of them).
    #[arg(long, default_value_t = BenchOptions::default().arm_steps)]
    pub arm_steps: usize,
    /// Steps of the Gymnasium environment's core under a random policy (20 Hz control).
    #[arg(long, default_value_t = BenchOptions::default().env_steps)]
    pub env_steps: usize,
    /// Print the table as JSON.
    #[arg(long)]
    pub json: bool,
    /// Also time a campaign of this scenario (TOML): each of its reference manifolds built
    /// alone, the campaign with them cached, and the campaign from an empty cache (in a scratch
    /// folder, on all cores; the paper scenario takes about 40 minutes on 2 cores).
    #[arg(long)]
    pub campaign: Option<std::path::PathBuf>,
}

/// The most steps one arm scene (or the environment) runs (about 10 minutes of the cross on a
/// slow core).
const MAX_ARM_STEPS: usize = 5_000_000;

pub fn bench_command(args: BenchArgs) -> Result<i32> {
    for (flag, steps) in [
        ("--arm-steps", args.arm_steps),
        ("--env-steps", args.env_steps),
    ] {
        if !(1..=MAX_ARM_STEPS).contains(&steps) {
            return Err(Error::Input(format!(
                "{flag} {steps}: expected 1 to {MAX_ARM_STEPS}"
            )));
        }
    }
    let scenario = args.campaign.as_deref().map(Scenario::load).transpose()?;
    let mut rows = run(&BenchOptions {
        arm_steps: args.arm_steps,
        env_steps: args.env_steps,
    })?;
    if let Some(scenario) = &scenario {
        rows.extend(campaign_rows(scenario)?);
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rows).expect("rows serialise")
        );
    } else {
        print!("{}", table(&rows));
    }
    Ok(0)
}
