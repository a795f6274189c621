//! `pegtwin bench`: the speed of a campaign's pieces on this machine.

use clap::Args;
use pegtwin::campaign::bench::{BenchOptions, run, table};
use pegtwin::error::{Error, Result};

#[derive(Args)]
pub struct BenchArgs {
    /// Physics steps measured on the cross's arm scene (the gear's runs a tenth of them).
    #[arg(long, default_value_t = BenchOptions::default().arm_steps)]
    pub arm_steps: usize,
    /// Print the table as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The most steps one arm scene runs (about 10 minutes of the cross on a slow core).
const MAX_ARM_STEPS: usize = 5_000_000;

pub fn bench_command(args: BenchArgs) -> Result<i32> {
    if !(1..=MAX_ARM_STEPS).contains(&args.arm_steps) {
        return Err(Error::Input(format!(
            "--arm-steps {}: expected 1 to {MAX_ARM_STEPS}",
            args.arm_steps
        )));
    }
    let rows = run(&BenchOptions {
        arm_steps: args.arm_steps,
    })?;
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
