//! Strands as uniform cubic B-splines: the geometry every tracer (Embree round/flat curves, the Rust BVH) consumes.
//!
//! **How a curve reaches its root and tip.** A uniform cubic B-spline does not pass through its control points. We
//! add one phantom point at each end, mirrored through the end point (P₋₁ = 2P₀ − P₁, Pₙ = 2Pₙ₋₁ − Pₙ₋₂), and use the
//! file's points as the remaining control points. Segment k uses control points k..k+3, so a strand of n file points
//! gives n + 2 control points and n − 1 segments. With the mirrored phantom the first segment starts exactly at
//! (P₋₁ + 4P₀ + P₁)/6 = P₀ and the last ends exactly at the tip; interior points are approximated, not interpolated
//! (the B-spline smooths the polyline, which is why the thesis chose it, §5.2). Radii get the same phantom rule, so
//! the root and tip radii are exact too.
//!
//! **Taper** (thesis §5.2): when the file gives no per-point thickness, the radius falls linearly from the default at
//! the root to half of it at the tip, by point index. A per-point thickness array in the file is used as it is.

use glam::Vec3;

use super::HairModel;

/// Flat arrays in the layout Embree's curve geometry wants, plus the per-strand shading data.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Strands {
    /// B-spline control points as (x, y, z, radius): Embree's `RTC_FORMAT_FLOAT4` vertex layout.
    pub control_points: Vec<[f32; 4]>,
    /// Index of each strand's first control point; `strand_count + 1` entries.
    pub strand_offsets: Vec<u32>,
    /// For each curve segment, the index of its first control point (Embree's `RTC_FORMAT_UINT` index buffer).
    pub segment_first: Vec<u32>,
    /// For each curve segment, the strand it belongs to (Embree's `primID` → strand).
    pub segment_strand: Vec<u32>,
    /// Per-strand opacity in [0, 1] used by shadow rays (1 − the file's transparency at the root).
    pub opacity: Vec<f32>,
    /// Per-strand linear RGB colour (the file's colour at the root).
    pub color: Vec<[f32; 3]>,
}

/// A point on a strand: position, derivative along the curve (root → tip, not normalised) and radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurvePoint {
    /// Position on the curve's centre line.
    pub position: Vec3,
    /// dP/du: points from root to tip; zero only for degenerate (repeated) control points.
    pub tangent: Vec3,
    /// Radius at this point.
    pub radius: f32,
}

/// Uniform cubic B-spline basis at `u` ∈ [0, 1].
#[inline]
pub fn bspline_basis(u: f32) -> [f32; 4] {
    let t = 1.0 - u;
    [
        t * t * t / 6.0,
        (3.0 * u * u * u - 6.0 * u * u + 4.0) / 6.0,
        (-3.0 * u * u * u + 3.0 * u * u + 3.0 * u + 1.0) / 6.0,
        u * u * u / 6.0,
    ]
}

/// Derivative of [`bspline_basis`] with respect to `u`.
#[inline]
fn bspline_basis_derivative(u: f32) -> [f32; 4] {
    let t = 1.0 - u;
    [
        -0.5 * t * t,
        (3.0 * u * u - 4.0 * u) * 0.5,
        (-3.0 * u * u + 2.0 * u + 1.0) * 0.5,
        0.5 * u * u,
    ]
}

impl Strands {
    /// Converts polylines to B-spline strands (phantom end points; taper when the file has no thickness).
    pub fn from_model(model: &HairModel) -> Self {
        let strand_count = model.strand_count();
        let mut out = Strands {
            control_points: Vec::with_capacity(model.points.len() + 2 * strand_count),
            strand_offsets: Vec::with_capacity(strand_count + 1),
            segment_first: Vec::with_capacity(model.points.len()),
            segment_strand: Vec::with_capacity(model.points.len()),
            opacity: Vec::with_capacity(strand_count),
            color: Vec::with_capacity(strand_count),
        };
        for s in 0..strand_count {
            let range = model.strand_range(s);
            let n = range.len();
            let pts = &model.points[range.clone()];
            let radius_at = |i: usize| {
                let r = model.radius[range.start + i];
                if model.radius_from_file {
                    r
                } else {
                    // thesis §5.2: root = default width, tip = half, linear in between.
                    r * (1.0 - 0.5 * i as f32 / (n - 1) as f32)
                }
            };
            let first = out.control_points.len() as u32;
            out.strand_offsets.push(first);
            let cp = |p: Vec3, r: f32| [p.x, p.y, p.z, r];
            // Phantom root: mirrored so the curve starts exactly at P0 with radius r0. The radius mirror is
            // kept positive for steep tapers.
            let (r0, r1) = (radius_at(0), radius_at(1));
            out.control_points
                .push(cp(2.0 * pts[0] - pts[1], (2.0 * r0 - r1).max(0.5 * r0)));
            for (i, p) in pts.iter().enumerate() {
                out.control_points.push(cp(*p, radius_at(i)));
            }
            let (rn, rm) = (radius_at(n - 1), radius_at(n - 2));
            out.control_points.push(cp(
                2.0 * pts[n - 1] - pts[n - 2],
                (2.0 * rn - rm).max(0.5 * rn),
            ));
            for k in 0..(n - 1) as u32 {
                out.segment_first.push(first + k);
                out.segment_strand.push(s as u32);
            }
            out.opacity.push(1.0 - model.transparency[range.start]);
            out.color.push(model.color[range.start]);
        }
        out.strand_offsets.push(out.control_points.len() as u32);
        out
    }

    /// Appends one strand given as B-spline control points (x, y, z, radius) and, for each of its segments, the
    /// index of the segment's first control point within `control_points`. Segments may share control points
    /// (segment k at k, as [`Strands::from_model`] lays them out) or have four of their own (segment k at 4k, as a
    /// basis converted segment by segment needs: neighbouring segments' converted points differ). `None` when a
    /// segment's four points reach past `control_points` or the strand has no segment.
    pub fn push_strand(
        &mut self,
        control_points: &[[f32; 4]],
        segment_first: &[u32],
        opacity: f32,
        color: [f32; 3],
    ) -> Option<()> {
        let n = control_points.len();
        if segment_first.is_empty() || segment_first.iter().any(|&f| f as usize + 4 > n) {
            return None;
        }
        if self.strand_offsets.is_empty() {
            self.strand_offsets.push(0);
        }
        let first = self.control_points.len() as u32;
        let strand = self.strand_count() as u32;
        self.control_points.extend_from_slice(control_points);
        self.segment_first
            .extend(segment_first.iter().map(|&f| first + f));
        self.segment_strand
            .extend(segment_first.iter().map(|_| strand));
        self.strand_offsets.push(self.control_points.len() as u32);
        self.opacity.push(opacity);
        self.color.push(color);
        Some(())
    }

    /// Appends every strand of `other` after this one's, its indices moved past this one's control points and
    /// strands.
    pub fn append(&mut self, other: &Strands) {
        if other.strand_count() == 0 {
            return;
        }
        if self.strand_offsets.is_empty() {
            self.strand_offsets.push(0);
        }
        let (cp, strand) = (self.control_points.len() as u32, self.strand_count() as u32);
        self.control_points.extend_from_slice(&other.control_points);
        self.strand_offsets
            .extend(other.strand_offsets[1..].iter().map(|&o| cp + o));
        self.segment_first
            .extend(other.segment_first.iter().map(|&f| cp + f));
        self.segment_strand
            .extend(other.segment_strand.iter().map(|&s| strand + s));
        self.opacity.extend_from_slice(&other.opacity);
        self.color.extend_from_slice(&other.color);
    }

    /// The segments of strand `s`: segments are stored strand after strand, so they are the run of
    /// `segment_strand` equal to `s`. A strand's segments may share control points (a file's polyline) or have
    /// four of their own ([`Strands::push_strand`]); walk them through `segment_first`, never through
    /// `strand_offsets`.
    pub fn segments_of(&self, s: usize) -> std::ops::Range<usize> {
        let lo = self.segment_strand.partition_point(|&t| (t as usize) < s);
        let hi = lo + self.segment_strand[lo..].partition_point(|&t| t as usize == s);
        lo..hi
    }

    /// Number of strands.
    pub fn strand_count(&self) -> usize {
        self.strand_offsets.len().saturating_sub(1)
    }

    /// Heap bytes of all arrays.
    pub fn bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.control_points.as_slice())
            + size_of_val(self.strand_offsets.as_slice())
            + size_of_val(self.segment_first.as_slice())
            + size_of_val(self.segment_strand.as_slice())
            + size_of_val(self.opacity.as_slice())
            + size_of_val(self.color.as_slice())
    }

    /// Number of cubic segments (Embree primitives).
    pub fn segment_count(&self) -> usize {
        self.segment_first.len()
    }

    /// Evaluates segment `segment` at curve parameter `u` ∈ [0, 1] (Embree's hit `u`).
    pub fn eval(&self, segment: u32, u: f32) -> CurvePoint {
        let first = self.segment_first[segment as usize] as usize;
        let cps = &self.control_points[first..first + 4];
        let (b, d) = (bspline_basis(u), bspline_basis_derivative(u));
        let mut position = Vec3::ZERO;
        let mut tangent = Vec3::ZERO;
        let mut radius = 0.0;
        for i in 0..4 {
            let p = Vec3::new(cps[i][0], cps[i][1], cps[i][2]);
            position += b[i] * p;
            tangent += d[i] * p;
            radius += b[i] * cps[i][3];
        }
        CurvePoint {
            position,
            tangent,
            radius,
        }
    }

    /// Bounds of the swept curves, inflated by the largest radius: (min, max). The convex-hull property of
    /// B-splines makes the control-point box conservative.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for c in &self.control_points {
            let p = Vec3::new(c[0], c[1], c[2]);
            lo = lo.min(p - Vec3::splat(c[3]));
            hi = hi.max(p + Vec3::splat(c[3]));
        }
        (lo, hi)
    }

    /// Whether every strand has opacity 1 (then a stochastic presence test always says present).
    pub fn all_opaque(&self) -> bool {
        self.opacity.iter().all(|&a| a >= 1.0)
    }

    /// [`tube_exit`] of a ray from `origin` along `dir` leaving segment `segment` at curve parameter `u` (a hit's
    /// `u`), from the curve's axis point, tangent and radius there; `None` where [`tube_exit`] is, or for a
    /// degenerate tangent.
    pub fn tube_exit_at(&self, segment: u32, u: f32, origin: Vec3, dir: Vec3) -> Option<f32> {
        let c = self.eval(segment, u);
        tube_exit(
            origin,
            dir,
            c.position,
            c.tangent.try_normalize()?,
            c.radius,
        )
    }

    /// Replaces every strand's opacity (a scene override of the file's transparency).
    pub fn set_opacity(&mut self, opacity: f32) {
        self.opacity.iter_mut().for_each(|o| *o = opacity);
    }
}

/// Rays leaving a fibre within this sine of its axis keep ignoring the whole strand: the tube exit lies up to
/// 2r / sin θ along the ray, where the straight local tube no longer stands for the curved one.
pub const TUBE_MIN_SIN: f32 = 0.5;

/// Relative margin on the fibre radius for [`tube_exit`]: the hit point Embree reports and the B-spline's swept
/// sphere deviate from the local straight tube by float error and curvature (r/R ≈ 1e-2 on the fur ball).
pub const TUBE_MARGIN: f32 = 0.05;

/// Where a ray from `origin` (on or inside the fibre) along `dir` leaves the fibre's local tube: the straight
/// cylinder of radius `radius` (1 + [`TUBE_MARGIN`]) around the line through `axis` along `tangent` (unit). The
/// ray parameter of the exit, in units of `dir`; `None` where that is not a good stand-in for the curved fibre
/// (the ray within asin [`TUBE_MIN_SIN`] of the axis, or a degenerate radius). A ray-facing ribbon of half-width
/// `radius` lies inside the same tube, so the exit also clears the flat curve the ray would see.
#[inline]
pub fn tube_exit(origin: Vec3, dir: Vec3, axis: Vec3, tangent: Vec3, radius: f32) -> Option<f32> {
    // Parts across the axis: |w⊥ + t d⊥|² = r'², the larger root.
    let w = origin - axis;
    let w_perp = w - tangent * w.dot(tangent);
    let d_perp = dir - tangent * dir.dot(tangent);
    let a = d_perp.length_squared();
    // Written so that NaNs fail too.
    let defined = a >= TUBE_MIN_SIN * TUBE_MIN_SIN * dir.length_squared() && radius > 0.0;
    if !defined {
        return None;
    }
    let r = radius * (1.0 + TUBE_MARGIN);
    let b = w_perp.dot(d_perp);
    let c = w_perp.length_squared() - r * r;
    // c ≤ 0 for an origin inside the margin tube, so the discriminant is ≥ b²; an origin outside it (beyond the
    // margin: not a hit on this fibre) has no well-defined exit.
    if c > 0.0 {
        return None;
    }
    let t = (-b + (b * b - a * c).sqrt()) / a;
    t.is_finite().then_some(t.max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_strands() -> HairModel {
        let points = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.5, 2.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 1.0),
        ];
        HairModel {
            strand_offsets: vec![0, 3, 5],
            radius: vec![0.1; 5],
            radius_from_file: false,
            transparency: vec![0.25; 5],
            color: vec![[1.0, 0.5, 0.25]; 5],
            points,
            ..Default::default()
        }
    }

    #[test]
    fn curve_starts_at_root_and_ends_at_tip() {
        let m = two_strands();
        let s = Strands::from_model(&m);
        assert_eq!(s.strand_count(), 2);
        assert_eq!(s.segment_count(), 2 + 1, "n points give n - 1 segments");
        assert_eq!(s.control_points.len(), 5 + 4);
        let root = s.eval(0, 0.0);
        let tip = s.eval(1, 1.0);
        assert!((root.position - m.points[0]).length() < 1e-6, "{root:?}");
        assert!((tip.position - m.points[2]).length() < 1e-6, "{tip:?}");
        // Taper: root radius = default, tip = half (thesis §5.2).
        assert!((root.radius - 0.1).abs() < 1e-6, "{}", root.radius);
        assert!((tip.radius - 0.05).abs() < 1e-6, "{}", tip.radius);
        assert!(root.tangent.y > 0.0, "tangent points root → tip");
        assert_eq!(s.segment_strand, vec![0, 0, 1]);
        assert!((s.opacity[1] - 0.75).abs() < 1e-6);
    }

    #[test]
    fn segments_join_continuously() {
        let s = Strands::from_model(&two_strands());
        let a = s.eval(0, 1.0);
        let b = s.eval(1, 0.0);
        assert!((a.position - b.position).length() < 1e-6);
        assert!(
            (a.tangent - b.tangent).length() < 1e-5,
            "C1 continuity: {a:?} {b:?}"
        );
    }

    #[test]
    fn strands_of_their_own_segments_append_after_shared_ones() {
        let mut s = Strands::from_model(&two_strands());
        let before = s.clone();
        let own: Vec<[f32; 4]> = (0..8).map(|i| [i as f32, 0.0, 0.0, 0.1]).collect();
        assert!(s.push_strand(&own, &[0, 4], 0.5, [0.25; 3]).is_some());
        assert_eq!(s.strand_count(), 3);
        assert_eq!(&s.segment_first[3..], &[9, 13]);
        assert_eq!(&s.segment_strand[3..], &[2, 2]);
        assert_eq!(s.strand_offsets, vec![0, 5, 9, 17]);
        assert_eq!(s.eval(4, 0.0).position, Vec3::new(5.0, 0.0, 0.0));
        assert!(s.push_strand(&own, &[5], 0.5, [0.25; 3]).is_none());
        let mut joined = before.clone();
        joined.append(&before);
        assert_eq!(joined.segment_first[3..], [9, 10, 14]);
        assert_eq!(joined.segment_strand[3..], [2, 2, 3]);
        assert_eq!(joined.strand_offsets, vec![0, 5, 9, 14, 18]);
        let mut empty = Strands::default();
        empty.append(&before);
        assert_eq!(empty.control_points, before.control_points);
        assert_eq!(empty.strand_offsets, before.strand_offsets);
    }

    #[test]
    fn file_thickness_is_not_tapered() {
        let mut m = two_strands();
        m.radius_from_file = true;
        let s = Strands::from_model(&m);
        assert!((s.eval(1, 1.0).radius - 0.1).abs() < 1e-6);
    }

    #[test]
    fn tube_exit_leaves_the_tube_across_the_axis() {
        // Fibre along x through the origin, radius 2; a ray from the top of the tube straight down crosses the
        // whole diameter (margin included).
        let r = 2.0;
        let t = tube_exit(Vec3::new(0.3, r, 0.0), -Vec3::Y, Vec3::ZERO, Vec3::X, r).unwrap();
        let r_margin = r * (1.0 + TUBE_MARGIN);
        assert!((t - (r + r_margin)).abs() < 1e-5, "{t}");
        // Leaving outwards: only the margin is left to cross.
        let t = tube_exit(Vec3::new(0.3, r, 0.0), Vec3::Y, Vec3::ZERO, Vec3::X, r).unwrap();
        assert!((t - r * TUBE_MARGIN).abs() < 1e-5, "{t}");
        // A tilted, unnormalised direction: the exit point lies on the margin tube.
        let (o, d) = (Vec3::new(0.0, 0.0, r), Vec3::new(1.0, 2.0, -1.0) * 3.0);
        let t = tube_exit(o, d, Vec3::ZERO, Vec3::X, r).unwrap();
        let p = o + t * d;
        assert!(
            ((p.y * p.y + p.z * p.z).sqrt() - r_margin).abs() < 1e-4,
            "{p}"
        );
    }

    #[test]
    fn tube_exit_is_undefined_along_the_fibre_and_outside_it() {
        let r = 1.0;
        let along = Vec3::new(1.0, 0.5, 0.0); // sin θ = 0.447 < TUBE_MIN_SIN
        assert_eq!(tube_exit(Vec3::Y, along, Vec3::ZERO, Vec3::X, r), None);
        assert_eq!(
            tube_exit(Vec3::Y * 1.2, -Vec3::Y, Vec3::ZERO, Vec3::X, r),
            None
        );
        assert_eq!(tube_exit(Vec3::Y, -Vec3::Y, Vec3::ZERO, Vec3::X, 0.0), None);
    }
}
