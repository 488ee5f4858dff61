//! `cuticle info`, `cuticle plot-bsdf` and `cuticle plot-csv`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use cuticle::hair;
use cuticle::scene::Scene;

use super::parse_resolution;

#[derive(clap::Args)]
pub struct PlotArgs {
    /// Take the `[material]` of this scene file (parameters included) instead of a model's defaults.
    scene: Option<PathBuf>,
    /// The model, with the papers' default parameters (ignored when a scene is given).
    #[arg(long, value_enum, default_value = "ishair")]
    material: MaterialName,
    /// Directory for the PNGs (created if needed).
    #[arg(short, long, default_value = "plots")]
    out: PathBuf,
    /// View direction's longitudinal angle θo, degrees.
    #[arg(long, default_value_t = 30.0, allow_hyphen_values = true)]
    theta_o: f32,
    /// θi of the azimuthal plot, degrees.
    #[arg(long, default_value_t = -30.0, allow_hyphen_values = true)]
    theta_i: f32,
    /// Relative azimuth φ of the longitudinal plot, degrees (180 shows TT).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    phi: f32,
    /// Directions drawn for the histogram.
    #[arg(long, default_value_t = 1_000_000)]
    samples: usize,
    /// Offset h = sin γo across the fibre, in [-1, 1], for models that depend on it (chiang); 0 = the centre.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    h: f32,
}

#[derive(clap::Args)]
pub struct PlotCsvArgs {
    /// The CSV table (a header line, then rows).
    file: PathBuf,
    /// The horizontal column.
    #[arg(long)]
    x: String,
    /// The vertical column. Rows where x or y is empty or not a number are left out.
    #[arg(long)]
    y: String,
    /// One curve per value of this column.
    #[arg(long)]
    by: Option<String>,
    /// Label each point with this column's value.
    #[arg(long)]
    point_label: Option<String>,
    /// Log10 horizontal axis.
    #[arg(long)]
    log_x: bool,
    /// Log10 vertical axis.
    #[arg(long)]
    log_y: bool,
    /// The chart title.
    #[arg(long, default_value = "")]
    title: String,
    /// The horizontal axis title (default: the column name).
    #[arg(long)]
    x_label: Option<String>,
    /// The vertical axis title (default: the column name).
    #[arg(long)]
    y_label: Option<String>,
    /// Directory for `<stem>.png` and `<stem>.svg` (created if needed).
    #[arg(short, long, default_value = ".")]
    out: PathBuf,
    /// File name of the chart, without extension (default: the table's).
    #[arg(long)]
    stem: Option<String>,
    /// Chart size WxH, pixels.
    #[arg(long, value_parser = parse_resolution, default_value = "960x640")]
    size: [u32; 2],
}

/// Model names for `plot-bsdf --material`.
#[derive(Clone, Copy, clap::ValueEnum)]
enum MaterialName {
    /// Kajiya & Kay 1989.
    KajiyaKay,
    /// Hery & Ramamoorthi 2012 (thesis §4.2).
    Marschner,
    /// Ou et al. 2012 (thesis §4.3).
    Ishair,
    /// Chiang et al. 2016, at offset `--h`.
    Chiang,
}

pub fn info_command(file: &Path) -> Result<()> {
    if cuticle::scene::is_usd(file) {
        println!("{}", cuticle::usd::summary(file, None)?);
        return Ok(());
    }
    // The header says how much the model needs: checked against the memory limit before reading it (a large
    // sparse file whose header matches its apparent size aborted in the allocator).
    let counts = hair::declared_counts(file)?;
    let (limit, source) = cuticle::render::budget::default_limit();
    cuticle::render::budget::estimate_model(counts)
        .check(limit, &source)
        .with_context(|| format!("{}: cannot describe it", file.display()))?;
    let model = hair::load(file)?;
    println!("file:         {}", file.display());
    println!("{}", model.summary());
    Ok(())
}

pub fn plot_command(args: PlotArgs) -> Result<()> {
    use cuticle::scene::MaterialConfig;
    let config = match &args.scene {
        Some(path) => Scene::load(path)?.material,
        None => {
            let name = match args.material {
                MaterialName::KajiyaKay => "kajiya-kay",
                MaterialName::Marschner => "marschner",
                MaterialName::Ishair => "ishair",
                MaterialName::Chiang => "chiang",
            };
            MaterialConfig::named(name).context("building the default material")?
        }
    };
    if !(args.h.is_finite() && args.h.abs() <= 1.0) {
        bail!("--h must be in [-1, 1], got {}", args.h);
    }
    let material = config.build().map_err(anyhow::Error::msg)?;
    let options = cuticle::plot::bsdf::PlotOptions {
        theta_o_deg: args.theta_o,
        theta_i_deg: args.theta_i,
        phi_deg: args.phi,
        samples: args.samples,
        ..Default::default()
    };
    let paths =
        cuticle::plot::bsdf::write_plots(&material.at(args.h), material.name, &args.out, &options)?;
    for p in paths {
        println!("wrote {}", p.display());
    }
    Ok(())
}

pub fn plot_csv_command(args: PlotCsvArgs) -> Result<()> {
    let text = std::fs::read_to_string(&args.file)
        .with_context(|| format!("cannot read {}", args.file.display()))?;
    let spec = cuticle::plot::CsvChart {
        x: args.x,
        y: args.y,
        by: args.by,
        point_label: args.point_label,
        log_x: args.log_x,
        log_y: args.log_y,
        title: args.title,
        x_label: args.x_label,
        y_label: args.y_label,
    };
    let chart = spec
        .line_chart(&text)
        .with_context(|| format!("{}", args.file.display()))?;
    let [w, h] = args.size;
    let figure = cuticle::plot::render(&chart, "csv", (w as usize, h as usize))?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let stem = match args.stem {
        Some(stem) => stem,
        None => args
            .file
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "chart".to_owned()),
    };
    for path in cuticle::plot::write_figure(&figure, &args.out, &stem)? {
        println!("wrote {}", path.display());
    }
    Ok(())
}
