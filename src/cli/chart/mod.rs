//! `pathtracer chart accuracy|scaling ...`: the charts of PERF.md, drawn by the project itself
//! (plotters, SVG).

mod accuracy;
mod peer;
mod peer_csv;
mod scaling;

use clap::Subcommand;

pub use accuracy::AccuracyArgs;
pub use scaling::ScalingArgs;

/// `pathtracer chart accuracy|scaling`.
#[derive(Subcommand, Debug, Clone)]
pub enum ChartCommand {
    Accuracy(AccuracyArgs),
    Scaling(ScalingArgs),
}

pub fn run(chart: ChartCommand) -> pathtracer::Result<()> {
    match chart {
        ChartCommand::Accuracy(a) => accuracy::run(a),
        ChartCommand::Scaling(a) => scaling::run(a),
    }
}
