//! `frfbayes check <CAMPAIGN>`: reads and validates a campaign and summarises it.
//! Warnings (ignored keys, stray files) go to stderr; any error is the library's.

use frfbayes::io::{Quantity, TestKind};
use std::path::PathBuf;

/// Arguments of `frfbayes check`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Campaign folder (with campaign.toml and tests/<name>/{test.toml,data.csv}).
    pub campaign: PathBuf,
}

fn quantity_name(q: Quantity) -> &'static str {
    match q {
        Quantity::Force => "force",
        Quantity::GroundAcceleration => "ground_acceleration",
        Quantity::Acceleration => "acceleration",
        Quantity::Displacement => "displacement",
    }
}

/// Reads the campaign and prints title, nominal model and tests.
pub fn run(args: Args) -> anyhow::Result<()> {
    let campaign = frfbayes::io::read_campaign(&args.campaign)?;
    for w in &campaign.warnings {
        eprintln!("warning: {w}");
    }
    let n = &campaign.nominal;
    println!("campaign {}", args.campaign.display());
    println!("title: {}", campaign.title);
    println!(
        "nominal model: {} with {} floors",
        n.structure,
        n.n_floors()
    );
    println!(
        "{:>8} {:>14} {:>24}",
        "floor", "mass_kg", "story_stiffness_n_per_m"
    );
    for (i, (m, k)) in n
        .floor_mass_kg
        .iter()
        .zip(&n.story_stiffness_n_per_m)
        .enumerate()
    {
        println!("{:>8} {:>14} {:>24}", i + 1, m, k);
    }
    println!("{} tests", campaign.tests.len());
    for t in &campaign.tests {
        let kind = match t.kind {
            TestKind::Hammer { excited_floor } => format!("hammer at floor {excited_floor}"),
            TestKind::ShakeTable => "shake table".to_string(),
        };
        let duration_s = t.n_samples() as f64 / t.sample_rate_hz;
        println!(
            "\ntest {}: {kind}, {} Hz, {} samples ({duration_s:.3} s), {} channels",
            t.name,
            t.sample_rate_hz,
            t.n_samples(),
            t.channels.len()
        );
        println!(
            "  {:<16} {:<20} {:>5} {:>6} {:>13}",
            "channel", "quantity", "floor", "unit", "peak_abs"
        );
        for (c, samples) in t.channels.iter().zip(&t.data) {
            let peak_abs = samples.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
            println!(
                "  {:<16} {:<20} {:>5} {:>6} {:>13.4e}",
                c.name,
                quantity_name(c.quantity),
                c.floor,
                c.unit,
                peak_abs
            );
        }
    }
    Ok(())
}
