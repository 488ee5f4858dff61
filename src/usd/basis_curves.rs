//! `BasisCurves` prims as B-spline strands ([`super::curves`] converts each basis).

use glam::{DMat4, Vec3};
use openusd::usd;

use crate::hair::{HairModel, Strands};

use super::curves::{self, Basis, Radius, Wrap};
use super::values::{floats, ints, vec3s};
use super::xform::{transform_points, world_radius_scale};
use super::MAX_POINTS;
use super::{prim_err, Reader, UsdError};

impl Reader<'_> {
    /// One `BasisCurves` prim as strands, world space.
    pub(super) fn curves(&mut self, prim: &usd::Prim, world: DMat4) -> Result<Strands, UsdError> {
        let pp = prim.path().clone();
        let bad = |m: String| prim_err(self.path, &pp, m);
        let ty = self.token(prim, "type", "cubic")?;
        let basis_name = self.token(prim, "basis", "bezier")?;
        let wrap_name = self.token(prim, "wrap", "nonperiodic")?;
        let basis = match (ty.as_str(), basis_name.as_str()) {
            ("linear", _) => Basis::Linear,
            ("cubic", "bezier") => Basis::Bezier,
            ("cubic", "bspline") => Basis::BSpline,
            ("cubic", "catmullRom") => Basis::CatmullRom,
            ("cubic", b) => {
                return Err(bad(format!(
                    "unknown basis {b:?} (bezier, bspline, catmullRom)"
                )))
            }
            (t, _) => return Err(bad(format!("unknown curve type {t:?} (cubic, linear)"))),
        };
        let wrap = match wrap_name.as_str() {
            "nonperiodic" => Wrap::Nonperiodic,
            "periodic" => Wrap::Periodic,
            "pinned" => Wrap::Pinned,
            w => {
                return Err(bad(format!(
                    "unknown wrap {w:?} (nonperiodic, periodic, pinned)"
                )))
            }
        };
        let counts = self
            .get_as(prim, "curveVertexCounts", "an int array", ints)?
            .unwrap_or_default();
        let points = self
            .get_as(prim, "points", "a point array", vec3s)?
            .unwrap_or_default();
        // Counts against the points before anything is allocated for them.
        if let Some(c) = counts.iter().position(|&c| c < 0) {
            return Err(bad(format!("curveVertexCounts[{c}] is {}", counts[c])));
        }
        let total: u64 = counts.iter().map(|&c| c as u64).sum();
        if total != points.len() as u64 {
            return Err(bad(format!(
                "curveVertexCounts add up to {total} vertices but there are {} points",
                points.len()
            )));
        }
        if total > MAX_POINTS {
            return Err(bad(format!(
                "{total} vertices is more than the reader's limit of {MAX_POINTS}"
            )));
        }
        let mut segments = Vec::with_capacity(counts.len());
        for (i, &c) in counts.iter().enumerate() {
            let n = c as usize;
            let s = curves::segment_count(basis, wrap, n)
                .ok_or_else(|| bad(format!("curve {i} has {n} vertices: no {ty} {basis_name} {wrap_name} curve has that many")))?;
            segments.push(s);
        }
        let nvary: usize = counts
            .iter()
            .zip(&segments)
            .map(|(&c, &s)| curves::varying_count(basis, wrap, c as usize, s))
            .sum();
        let ncurves = counts.len();
        let expect = |interp: &str| match interp {
            "constant" => Some(1),
            "uniform" => Some(ncurves),
            "vertex" => Some(points.len()),
            "varying" | "faceVarying" => Some(nvary),
            _ => None,
        };
        // Widths: diameters; their interpolation defaults to vertex.
        let widths = self.get_as(prim, "widths", "a float array", floats)?;
        let widths_interp = self.interpolation(prim, "widths", "vertex");
        let widths = match widths {
            Some(w) if w.is_empty() => None,
            Some(w) => {
                let want = expect(&widths_interp).ok_or_else(|| {
                    bad(format!("widths: unknown interpolation {widths_interp:?}"))
                })?;
                if w.len() != want {
                    return Err(bad(format!(
                        "widths has {} values; {widths_interp} interpolation needs {want}",
                        w.len()
                    )));
                }
                if let Some(i) = w.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
                    return Err(bad(format!("widths[{i}] is {} (must be >= 0)", w[i])));
                }
                Some(w.into_iter().map(|w| 0.5 * w).collect::<Vec<f32>>())
            }
            None => None,
        };
        let color = self.primvar3(prim, "primvars:displayColor", &expect)?;
        let opacity = self.primvar1(prim, "primvars:displayOpacity", &expect)?;
        let pts: Vec<Vec3> = transform_points(&points, world);
        if let Some(i) = pts
            .iter()
            .position(|p| !p.is_finite() || p.abs().max_element() > crate::ray::MAX_SCENE_COORD)
        {
            return Err(bad(format!(
                "point {i} at {:?} is not finite or farther than {:e} from the origin",
                pts[i].to_array(),
                crate::ray::MAX_SCENE_COORD
            )));
        }
        let scale = world_radius_scale(world);
        // Each curve's colour and opacity: the primvar's value at its root.
        let (mut clamped_color, mut clamped_opacity) = (0usize, 0usize);
        let mut roots = Vec::with_capacity(ncurves);
        let (mut v, mut vary) = (0usize, 0usize);
        for (c, (&n, &s)) in counts.iter().zip(&segments).enumerate() {
            let pick = |interp: &str| match interp {
                "constant" => 0,
                "uniform" => c,
                "vertex" => v,
                _ => vary,
            };
            let col = color
                .as_ref()
                .map_or([1.0; 3], |(x, interp)| x[pick(interp)]);
            let col_c = col.map(|x| if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) });
            clamped_color += usize::from(col_c != col);
            let op = opacity.as_ref().map_or(1.0, |(x, interp)| x[pick(interp)]);
            let op_c = if op.is_nan() { 1.0 } else { op.clamp(0.0, 1.0) };
            clamped_opacity += usize::from(op_c.to_bits() != op.to_bits());
            roots.push((col_c, op_c));
            v += n as usize;
            vary += curves::varying_count(basis, wrap, n as usize, s);
        }
        let mut out = Strands::default();
        let mut clamped_radius = 0;
        let no_widths = widths.is_none();
        let pinned_bspline = basis == Basis::BSpline
            && wrap == Wrap::Pinned
            && widths_interp != "varying"
            && widths_interp != "faceVarying";
        if pinned_bspline {
            // The `.hair` path: one model, converted by `Strands::from_model` (phantoms, taper without widths).
            let mut model = HairModel {
                points: pts,
                strand_offsets: Vec::with_capacity(ncurves + 1),
                radius: Vec::with_capacity(points.len()),
                radius_from_file: !no_widths,
                transparency: Vec::with_capacity(points.len()),
                color: Vec::with_capacity(points.len()),
                format: "usd".into(),
                info: String::new(),
            };
            model.strand_offsets.push(0);
            let mut v = 0usize;
            for (c, &n) in counts.iter().enumerate() {
                let n = n as usize;
                let (col, op) = roots[c];
                for i in 0..n {
                    let r = match &widths {
                        None => self.default_radius,
                        Some(w) => match widths_interp.as_str() {
                            "constant" => w[0],
                            "uniform" => w[c],
                            _ => w[v + i],
                        },
                    };
                    model.radius.push(r * scale);
                }
                model.transparency.extend(std::iter::repeat_n(1.0 - op, n));
                model.color.extend(std::iter::repeat_n(col, n));
                v += n;
                model.strand_offsets.push(v as u32);
            }
            out = Strands::from_model(&model);
            // The opacity as the file gives it (not 1 − (1 − opacity)).
            for (o, r) in out.opacity.iter_mut().zip(&roots) {
                *o = r.1;
            }
        } else {
            let (mut cps, mut first) = (Vec::new(), Vec::new());
            let (mut v, mut vary) = (0usize, 0usize);
            let mut taper = Vec::new();
            for (c, (&n, &s)) in counts.iter().zip(&segments).enumerate() {
                let n = n as usize;
                let nv = curves::varying_count(basis, wrap, n, s);
                let scaled: Vec<f32>;
                let radius = match (&widths, widths_interp.as_str()) {
                    (None, _) => {
                        taper.clear();
                        taper.extend((0..n).map(|i| {
                            self.default_radius * scale * (1.0 - 0.5 * i as f32 / (n - 1) as f32)
                        }));
                        Radius::Vertex(&taper)
                    }
                    (Some(w), "constant") => Radius::Constant(w[0] * scale),
                    (Some(w), "uniform") => Radius::Constant(w[c] * scale),
                    (Some(w), "vertex") => {
                        scaled = w[v..v + n].iter().map(|r| r * scale).collect();
                        Radius::Vertex(&scaled)
                    }
                    (Some(w), _) => {
                        scaled = w[vary..vary + nv].iter().map(|r| r * scale).collect();
                        Radius::Varying(&scaled)
                    }
                };
                cps.clear();
                first.clear();
                clamped_radius +=
                    curves::convert(basis, wrap, &pts[v..v + n], radius, &mut cps, &mut first);
                let (col, op) = roots[c];
                out.push_strand(&cps, &first, op, col)
                    .ok_or_else(|| bad(format!("curve {c}: no segment")))?;
                v += n;
                vary += nv;
            }
        }
        if clamped_radius > 0 {
            self.warn(&pp, &format!("{clamped_radius} converted control point radii were below 0 and are clamped to 0"));
        }
        if clamped_color > 0 {
            self.warn(
                &pp,
                &format!("displayColor of {clamped_color} curves clamped to [0, 1]"),
            );
        }
        if clamped_opacity > 0 {
            self.warn(
                &pp,
                &format!("displayOpacity of {clamped_opacity} curves clamped to [0, 1]"),
            );
        }
        if scale != 1.0 {
            self.warn(
                &pp,
                &format!("widths scaled by the transform's mean scale {scale}"),
            );
        }
        Ok(out)
    }
}
