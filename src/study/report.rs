//! `cuticle study all [SCENE]`: every kind of [`super::kinds::ALL`] on one scene, and one Markdown report
//! (`report.md`) embedding their charts, with a table of the headline read-outs at the top; then `stress`
//! ([`super::stress`]), whose failure lines join the headline table and whose `stress.md` the report links.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::cache::write_text;
use super::framework::{run_kind, KindReport, StudyConfig};
use super::kinds;
use super::stress::{self, StressReport};
use super::{SceneFile, StudyError};

/// What `all` ran and wrote.
#[derive(Debug, Clone)]
pub struct AllReport {
    /// One report per kind, in [`kinds::ALL`] order.
    pub kinds: Vec<KindReport>,
    /// The stress cases (run after the kinds).
    pub stress: StressReport,
    /// The Markdown report.
    pub markdown: PathBuf,
    /// Every file written, in order: each kind's ([`KindReport::files`]), the stress study's, then `report.md` (not
    /// the cached references).
    pub files: Vec<PathBuf>,
}

/// Runs every kind on `scene` (a scene file or the default scene) and writes `report.md` into the output directory.
pub fn run_all(scene: &SceneFile, config: &StudyConfig) -> Result<AllReport, StudyError> {
    let mut reports = Vec::new();
    for name in kinds::ALL {
        let kind = kinds::by_name(name, config.quick)
            .expect("every name of ALL is a kind")
            .map_err(|e| StudyError::Config(format!("study {name}: {e}")))?;
        reports.push(run_kind(scene, &kind, config)?);
    }
    let stress = stress::run(scene, config)?;
    let mut all = reports.clone();
    all.push(stress.report.clone());
    let mut md = markdown_report(scene, config, &all);
    let _ = writeln!(
        md,
        "\nPer case and method, with the skipped cases: [stress.md](stress.md)."
    );
    let markdown = config.out_dir.join("report.md");
    write_text(&markdown, &md)?;
    let files = reports
        .iter()
        .chain([&stress.report])
        .flat_map(|r| r.files.iter().cloned())
        .chain([markdown.clone()])
        .collect();
    Ok(AllReport {
        kinds: reports,
        stress,
        markdown,
        files,
    })
}

/// The file name of `path` (charts are written beside the report).
fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The Markdown text of the report.
pub fn markdown_report(scene: &SceneFile, config: &StudyConfig, reports: &[KindReport]) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# cuticle study all: {scene}\n");
    let _ = writeln!(
        md,
        "{} seeds per point, references at {} spp unless a study says otherwise{}. Written by `cuticle study all{}`; every number below is in \
         the CSVs beside this file.\n",
        config.seeds,
        config.reference_spp,
        if config.quick { ", quick mode (tiny images, short sweeps: a smoke test, not a result)" } else { "" },
        if config.quick { " --quick" } else { "" },
    );
    let _ = writeln!(
        md,
        "## Headline read-outs\n\n| study | read-out |\n|---|---|"
    );
    for r in reports {
        for line in &r.readouts {
            let _ = writeln!(md, "| {} | {} |", r.kind.name, line.replace('|', "/"));
        }
    }
    for r in reports {
        let _ = writeln!(md, "\n## {}: {}\n", r.kind.name, r.kind.title);
        let _ = writeln!(
            md,
            "{}×{} film{}, references at {} spp.\n",
            r.resolution[0],
            r.resolution[1],
            r.kind
                .budget
                .crop
                .map(|_| " (the centred window of the study's film)")
                .unwrap_or_default(),
            r.reference_spp
        );
        for (reference, run) in r.kind.references.iter().zip(&r.references) {
            let _ = writeln!(
                md,
                "- reference {}: `{}`, {}{}",
                reference.label,
                file_name(&run.path),
                run.seconds
                    .map(|s| format!("{s:.2} s"))
                    .unwrap_or_else(|| "time not recorded".into()),
                if run.cached { " (cached)" } else { "" }
            );
        }
        for line in &r.reference_checks {
            let _ = writeln!(md, "- {line}");
        }
        for f in &r.files {
            if f.extension().is_some_and(|e| e == "png") {
                let _ = writeln!(md, "\n![{}]({})", file_name(f), file_name(f));
            }
        }
        let _ = writeln!(
            md,
            "\n| method | settings | render s (sd) | RMSE (sd) | SSIM | fireflies | NaN/Inf | mean diff | peak MB |\n|---|---|---|---|---|---|---|---|---|"
        );
        for s in &r.summaries {
            let v = &r.kind.variants[s.variant];
            let _ = writeln!(
                md,
                "| {} | {} | {:.3} ({:.3}) | {:.3e} ({:.1e}) | {:.4} | {:.1} | {} | {:+.2} % | {} |",
                v.method,
                v.settings,
                s.render_s.mean,
                s.render_s.sd,
                s.rmse.mean,
                s.rmse.sd,
                s.ssim.mean,
                s.fireflies.mean,
                s.non_finite,
                100.0 * s.mean_diff.mean,
                s.peak_bytes.map(|b| format!("{:.0}", b as f64 / 1e6)).unwrap_or_default()
            );
        }
    }
    md
}
