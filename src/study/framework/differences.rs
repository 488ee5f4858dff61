//! Differences between two series rendered with the same seeds ([`Kind::differences`]): the RMSE between their
//! images per setting and seed, the read-out lines, the CSV and the |A − B| images; a measurement of its own
//! beside the error against the references.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::super::figures;
use super::super::StudyError;
use super::charts::x_label;
use super::readouts::setting_words;
use super::run::Judge;
use super::tables::{finish_csv, sci};
use super::{Difference, Kind, Point};
use crate::image::{self, Image};

/// The R, G, B values of every pixel of a render, row-major.
pub(super) fn rgb_pixels(image: &Image) -> Result<Vec<glam::Vec3>, StudyError> {
    let index = |c: &str| {
        image
            .channel_index(c)
            .ok_or_else(|| StudyError::Config(format!("the render has no {c} channel")))
    };
    let [r, g, b] = [index("R")?, index("G")?, index("B")?];
    let n = image.channels.len();
    Ok(image
        .data
        .chunks_exact(n)
        .map(|p| glam::Vec3::new(p[r], p[g], p[b]))
        .collect())
}

/// RMSE between two pixel lists, over R, G, B.
pub(super) fn rgb_rmse(a: &[glam::Vec3], b: &[glam::Vec3]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| f64::from((*p - *q).length_squared()))
        .sum();
    (sum / (3 * a.len().max(1)) as f64).sqrt()
}

/// For each pair of [`Kind::differences`], each variant of A with a variant of B at the same setting, and each
/// seed both rendered: the RMSE between their images (see the module docs).
pub(super) fn differences(
    kind: &Kind,
    points: &[Point],
    images: &HashMap<(usize, u32), Vec<glam::Vec3>>,
) -> Vec<Difference> {
    let mut out = Vec::new();
    for (a, b) in &kind.differences {
        for pa in points
            .iter()
            .filter(|p| kind.variants[p.variant].series == *a)
        {
            let x = kind.variants[pa.variant].x;
            let partner = points.iter().find(|p| {
                let v = &kind.variants[p.variant];
                v.series == *b && v.x == x && p.seed == pa.seed
            });
            let Some(pb) = partner else { continue };
            let (Some(ia), Some(ib)) = (
                images.get(&(pa.variant, pa.seed)),
                images.get(&(pb.variant, pb.seed)),
            ) else {
                continue;
            };
            out.push(Difference {
                a: a.clone(),
                b: b.clone(),
                x,
                seed: pa.seed,
                rmse: rgb_rmse(ia, ib),
                rmse_a: pa.rmse,
                rmse_b: pb.rmse,
            });
        }
    }
    out
}

/// Per pair: the images' difference at the largest common setting against their errors.
pub(super) fn difference_readouts(kind: &Kind, differences: &[Difference]) -> Vec<String> {
    kind.differences
        .iter()
        .filter_map(|(a, b)| {
            let of_pair = || differences.iter().filter(|d| d.a == *a && d.b == *b);
            let x = of_pair().map(|d| d.x).reduce(f64::max)?;
            let at: Vec<&Difference> = of_pair().filter(|d| d.x == x).collect();
            let mean = |f: fn(&Difference) -> f64| at.iter().map(|d| f(d)).sum::<f64>() / at.len() as f64;
            let (d, ea, eb) = (mean(|d| d.rmse), mean(|d| d.rmse_a), mean(|d| d.rmse_b));
            let percent = 100.0 * d / ea.min(eb);
            Some(format!(
                "{a} against {b}, same seeds: their images differ by RMSE {d:.2e} at {} (mean of {} seeds), \
                 {percent:.2} % of the smaller of their RMSEs against the reference ({ea:.2e}, {eb:.2e})",
                setting_words(&kind.x_label, &x_label(x)),
                at.len(),
            ))
        })
        .collect()
}

/// Header of `<kind>-differences.csv`.
pub const DIFFERENCE_HEADER: &str = "series_a,series_b,x,seed,diff_rmse,rmse_a,rmse_b";

/// `<kind>-differences.csv` ([`DIFFERENCE_HEADER`]).
pub fn differences_csv(differences: &[Difference]) -> Result<String, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(DIFFERENCE_HEADER.split(','))?;
    for d in differences {
        w.write_record([
            d.a.clone(),
            d.b.clone(),
            x_label(d.x),
            d.seed.to_string(),
            sci(d.rmse),
            sci(d.rmse_a),
            sci(d.rmse_b),
        ])?;
    }
    finish_csv(w)
}

/// `<kind>-diff-<a>-vs-<b>.png` per pair: |A − B| at the largest setting both rendered, their first seed, scaled
/// so that the reference's 99th percentile (largest channel) is white.
pub(super) fn difference_images(
    kind: &Kind,
    judges: &[Judge],
    images: &HashMap<(usize, u32), Vec<glam::Vec3>>,
    [width, height]: [u32; 2],
    dir: &Path,
) -> Result<Vec<PathBuf>, StudyError> {
    let mut files = Vec::new();
    for (a, b) in &kind.differences {
        let both = images
            .keys()
            .filter(|(i, _)| kind.variants[*i].series == *a)
            .filter_map(|&(i, seed)| {
                let x = kind.variants[i].x;
                let j = (0..kind.variants.len()).find(|&j| {
                    let v = &kind.variants[j];
                    v.series == *b && v.x == x && images.contains_key(&(j, seed))
                })?;
                Some((x, seed, i, j))
            })
            .max_by(|p, q| p.0.total_cmp(&q.0).then(q.1.cmp(&p.1)));
        let Some((_, seed, i, j)) = both else {
            continue;
        };
        let reference = &judges[kind.variants[i].reference].reference;
        let white = figures::p99_largest_channel(rgb_pixels(reference)?)
            .filter(|&w| w > 0.0)
            .unwrap_or(1.0);
        let (w, h) = (width as usize, height as usize);
        let mut out = Image::new(w, h, vec!["R".into(), "G".into(), "B".into()]);
        for (k, (p, q)) in images[&(i, seed)]
            .iter()
            .zip(&images[&(j, seed)])
            .enumerate()
        {
            let d = (*p - *q).abs() / white;
            for c in 0..3 {
                out.set(k % w, k / w, c, d[c]);
            }
        }
        let slug = |s: &str| s.replace(' ', "-");
        let path = dir.join(format!("{}-diff-{}-vs-{}.png", kind.name, slug(a), slug(b)));
        image::write(&path, &out)?;
        files.push(path);
    }
    Ok(files)
}
