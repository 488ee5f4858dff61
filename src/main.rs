//! The `cuticle` command line: parses arguments, calls the library, prints. The commands live in [`cli`].

mod cli;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};

/// cuticle: a physically based hair renderer (Embree curves, thesis hair BSDFs, OpenImageIO output).
#[derive(Parser)]
#[command(version, about, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an EXR (beauty + AOVs) and a PNG preview beside it.
    Render(cli::render::RenderArgs),
    /// Assemble the tiles of `render --tile`/`--crop` into one frame (EXR + PNG preview), checking they are of one
    /// job and cover every pixel exactly once.
    Merge(cli::render::MergeArgs),
    /// Describe a hair file: strands, points, bounds, thickness statistics, format.
    Info {
        /// A `.hair`, `.tfx` or USD (`.usda`, `.usdc`, `.usdz`, `.usd`) file.
        file: PathBuf,
    },
    /// Plot a fibre model's lobes (like the thesis' figure 4) and its sampled-vs-analytic pdf histograms.
    PlotBsdf(cli::tools::PlotArgs),
    /// Chart one column of a CSV table against another (PNG and SVG), one curve per value of a column.
    PlotCsv(cli::tools::PlotCsvArgs),
    /// Benchmarks (not tests): print throughput figures.
    #[command(subcommand)]
    Bench(cli::bench::BenchCommand),
    /// Studies: measured comparisons written to a directory (CSV tables, charts, crops).
    #[command(subcommand)]
    Study(cli::study::StudyCommand),
}

fn run() -> Result<()> {
    match Cli::parse().command {
        Command::Render(args) => cli::render::render_command(args),
        Command::Merge(args) => cli::render::merge_command(&args),
        Command::Info { file } => cli::tools::info_command(&file),
        Command::PlotBsdf(args) => cli::tools::plot_command(args),
        Command::PlotCsv(args) => cli::tools::plot_csv_command(args),
        Command::Bench(b) => cli::bench::bench_command(b),
        Command::Study(s) => cli::study::study_command(s),
    }
}

/// The CPU features of the build target (`.cargo/config.toml`: x86-64-v3) that this CPU lacks; empty elsewhere.
fn missing_cpu_features() -> Vec<&'static str> {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        let mut missing = Vec::new();
        if !std::arch::is_x86_feature_detected!("avx2") {
            missing.push("avx2");
        }
        if !std::arch::is_x86_feature_detected!("fma") {
            missing.push("fma");
        }
        if !std::arch::is_x86_feature_detected!("bmi2") {
            missing.push("bmi2");
        }
        missing
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    Vec::new()
}

fn main() -> ExitCode {
    let missing = missing_cpu_features();
    if !missing.is_empty() {
        eprintln!(
            "cuticle: error: this build targets x86-64-v3 and this CPU lacks {}; rebuild for it with \
             RUSTFLAGS=\"-C target-cpu=x86-64\" cargo build --release",
            missing.join(", ")
        );
        return ExitCode::from(2);
    }
    // A file-size limit (`ulimit -f`) sends SIGXFSZ, whose default action ends the process with no message and may
    // leave a temporary file; with a handler the write fails with EFBIG instead, and the error path reports it and
    // removes what it staged.
    #[cfg(unix)]
    let _ = signal_hook::flag::register(
        signal_hook::consts::SIGXFSZ,
        std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false)),
    );
    let result = run();
    // No exit while OpenImageIO is still being loaded in the background (image::finish_preload says why).
    cuticle::image::finish_preload();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!(
                "cuticle: error: {}",
                cuticle::util::report::capped(&cuticle::util::report::chain(e.as_ref()))
            );
            // A render stopped by a signal exits as the signal's convention says (130, 143); any other error 2.
            use cuticle::farm::FarmError;
            let farm = match e.downcast_ref::<cuticle::job::JobError>() {
                Some(cuticle::job::JobError::Farm(f)) => Some(f),
                _ => e.downcast_ref::<FarmError>(),
            };
            match farm {
                Some(FarmError::Interrupted(i)) => ExitCode::from(i.exit_code()),
                _ => ExitCode::from(2),
            }
        }
    }
}
