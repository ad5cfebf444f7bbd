//! One module per command; [`run`] dispatches the parsed command line.

mod bake;
mod bench;
mod bench_lightmap;
mod bench_transfer;
mod demo;
mod hemi;
mod hemi_scaling;
mod render;
mod ssv;
mod ssv_frame;
mod verify;

use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::cli::{BenchCommand, Command, VerifyArgs, VerifyCommand};
use crate::error::Result;

/// Runs the chosen command.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Demo(args) => demo::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Bake(args) => bake::run(&args),
        Command::Merge(args) => bake::run_merge(&args),
        Command::Bench(BenchCommand::Raycast(args)) => bench::run_raycast(&args),
        Command::Bench(BenchCommand::Hemi(args)) => hemi::run_bench(&args),
        Command::Bench(BenchCommand::Transfer(args)) => bench_transfer::run(&args),
        Command::Bench(BenchCommand::Lightmap(args)) => bench_lightmap::run(&args),
        Command::Bench(BenchCommand::Ssv(args)) => ssv::run_bench(&args),
        Command::Verify(VerifyArgs {
            what: Some(VerifyCommand::Ssv(args)),
            ..
        }) => ssv::run_verify(&args),
        Command::Verify(VerifyArgs {
            what: Some(VerifyCommand::Hemi(args)),
            ..
        }) => hemi::run_verify(&args),
        Command::Verify(VerifyArgs {
            what: Some(VerifyCommand::Raycast(args)),
            ..
        }) => verify::run(&args),
        Command::Verify(VerifyArgs { raycast, .. }) => verify::run(&raycast),
    }
}

/// `path` made absolute against the current folder, for messages that must say
/// exactly where a file went.
fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

/// A duration as `12.3 ms` or `4.56 s`.
fn format_duration(duration: Duration) -> String {
    let seconds = duration.as_secs_f64();
    if seconds < 1.0 {
        format!("{:.1} ms", seconds * 1e3)
    } else {
        format!("{seconds:.2} s")
    }
}

/// A rate of `unit` per second, as `1.23 M rays/s` or `45.6 k rays/s`.
fn format_rate(per_second: f64, unit: &str) -> String {
    if per_second >= 1e6 {
        format!("{:.2} M {unit}/s", per_second / 1e6)
    } else if per_second >= 1e3 {
        format!("{:.1} k {unit}/s", per_second / 1e3)
    } else {
        format!("{per_second:.0} {unit}/s")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_are_readable() {
        assert_eq!(format_duration(Duration::from_millis(12)), "12.0 ms");
        assert_eq!(format_duration(Duration::from_millis(4560)), "4.56 s");
        assert_eq!(format_rate(1_234_000.0, "rays"), "1.23 M rays/s");
        assert_eq!(format_rate(45_600.0, "rays"), "45.6 k rays/s");
    }
}
