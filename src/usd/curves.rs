//! `UsdGeomBasisCurves` → the uniform cubic B-spline control points (x, y, z, radius) the tracers intersect, by an
//! exact change of basis.
//!
//! A cubic segment is P(u) = [u³ u² u 1] · M · [P₀ P₁ P₂ P₃]ᵀ for its basis matrix M. The B-spline points of the
//! same curve are Q = M_B⁻¹ · M · P ([`BEZIER_TO_BSPLINE`], [`CATMULL_ROM_TO_BSPLINE`], computed in exact
//! fractions). Neighbouring segments' converted points differ, so every converted segment gets four control points
//! of its own (segment k at 4k). A B-spline curve needs no conversion: its points are the control points and the
//! segments share them (segment k at k). A linear segment A → B is the B-spline segment of points
//! (2A − B, A, B, 2B − A), exactly linear in u (the uniform B-spline reproduces linear functions).
//!
//! Segments per curve of n vertices (the UsdGeomBasisCurves schema): cubic nonperiodic n − 3 (Bézier (n − 1)/3,
//! vstep 3), pinned n − 1 (Bézier pinned is nonperiodic), periodic n (Bézier n/3); linear n − 1, periodic n. Pinned
//! B-spline and Catmull-Rom curves get a phantom point at each end, P₋₁ = 2P₀ − P₁ and Pₙ = 2Pₙ₋₁ − Pₙ₋₂ (the rule
//! [`crate::hair::Strands::from_model`] uses), so they start and end on their end points.
//!
//! Radii are half the file's widths. Per-vertex widths follow the curve's basis (converted like the positions);
//! per-segment-end (`varying`) widths are linear along each segment, written with the linear rule above; constant
//! and per-curve widths are the same at all four points. A converted radius below zero (a Catmull-Rom overshoot,
//! or the linear rule's outer points when one end is more than twice the other) is clamped to 0 and counted: the
//! tracers need radii ≥ 0.

use glam::{DVec3, Vec3};

/// The curve's basis and type (`type = "linear"` ignores the basis).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Basis {
    /// Cubic Bézier, vstep 3.
    Bezier,
    /// Uniform cubic B-spline.
    BSpline,
    /// Catmull-Rom.
    CatmullRom,
    /// Straight segments between the vertices.
    Linear,
}

/// The schema's `wrap`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wrap {
    /// Open curves.
    Nonperiodic,
    /// Closed curves: the last segment returns to the first vertex.
    Periodic,
    /// Open curves through their end points (phantom points for B-spline and Catmull-Rom).
    Pinned,
}

/// The radius of one curve, from the file's widths (half of them) or the reader's default.
#[derive(Debug, Clone, Copy)]
pub enum Radius<'a> {
    /// One radius for the whole curve (`constant` and `uniform` widths).
    Constant(f32),
    /// One radius per vertex, interpolated with the curve's basis.
    Vertex(&'a [f32]),
    /// One radius per segment end, linear along each segment (`varying` and `faceVarying` widths).
    Varying(&'a [f32]),
}

/// M_B⁻¹ · M_Bézier: row j gives B-spline point j from the four Bézier points.
pub const BEZIER_TO_BSPLINE: [[f64; 4]; 4] = [
    [6.0, -7.0, 2.0, 0.0],
    [0.0, 2.0, -1.0, 0.0],
    [0.0, -1.0, 2.0, 0.0],
    [0.0, 2.0, -7.0, 6.0],
];

/// M_B⁻¹ · M_CatmullRom: row j gives B-spline point j from the four Catmull-Rom points.
pub const CATMULL_ROM_TO_BSPLINE: [[f64; 4]; 4] = [
    [7.0 / 6.0, -2.0 / 3.0, 5.0 / 6.0, -1.0 / 3.0],
    [-1.0 / 3.0, 11.0 / 6.0, -2.0 / 3.0, 1.0 / 6.0],
    [1.0 / 6.0, -2.0 / 3.0, 11.0 / 6.0, -1.0 / 3.0],
    [-1.0 / 3.0, 5.0 / 6.0, -2.0 / 3.0, 7.0 / 6.0],
];

/// Whether the wrap adds phantom end points for this basis.
fn phantoms(basis: Basis, wrap: Wrap) -> bool {
    wrap == Wrap::Pinned && matches!(basis, Basis::BSpline | Basis::CatmullRom)
}

/// Segments of a curve of `n` vertices, or `None` when `n` vertices make no valid curve of this kind.
pub fn segment_count(basis: Basis, wrap: Wrap, n: usize) -> Option<usize> {
    let periodic = wrap == Wrap::Periodic;
    match basis {
        Basis::Linear => (n >= 2).then(|| if periodic { n } else { n - 1 }),
        Basis::Bezier if periodic => (n >= 3 && n.is_multiple_of(3)).then_some(n / 3),
        Basis::Bezier => (n >= 4 && (n - 4).is_multiple_of(3)).then_some((n - 1) / 3),
        Basis::BSpline | Basis::CatmullRom => match wrap {
            Wrap::Periodic => (n >= 3).then_some(n),
            Wrap::Pinned => (n >= 2).then_some(n - 1),
            Wrap::Nonperiodic => (n >= 4).then_some(n - 3),
        },
    }
}

/// Values a `varying` primvar has on a curve of `n` vertices and `segments` segments: one per segment end (a
/// closed curve's last end is its first), one per vertex on a linear curve.
pub fn varying_count(basis: Basis, wrap: Wrap, n: usize, segments: usize) -> usize {
    match (basis, wrap) {
        (Basis::Linear, _) => n,
        (_, Wrap::Periodic) => segments,
        _ => segments + 1,
    }
}

/// The vertices segment `k` uses (indices into the vertices, after phantom points where the wrap adds them), and
/// how many of the four are meaningful (2 for a linear segment).
fn segment_vertices(basis: Basis, wrap: Wrap, n: usize, k: usize) -> [usize; 4] {
    let at = |i: usize| if wrap == Wrap::Periodic { i % n } else { i };
    match basis {
        Basis::Linear => [at(k), at(k + 1), 0, 0],
        Basis::Bezier => std::array::from_fn(|j| at(3 * k + j)),
        Basis::BSpline | Basis::CatmullRom => std::array::from_fn(|j| at(k + j)),
    }
}

/// The vertices with the phantom points of a pinned curve added (or as they are).
fn with_phantoms<T: Copy>(basis: Basis, wrap: Wrap, v: &[T], mirror: impl Fn(T, T) -> T) -> Vec<T> {
    if !phantoms(basis, wrap) {
        return v.to_vec();
    }
    let n = v.len();
    let mut out = Vec::with_capacity(n + 2);
    out.push(mirror(v[0], v[1]));
    out.extend_from_slice(v);
    out.push(mirror(v[n - 1], v[n - 2]));
    out
}

/// Four B-spline values from a segment's values in the curve's basis (linear: the first two).
fn convert4<T>(basis: Basis, q: [T; 4]) -> [T; 4]
where
    T: Copy
        + std::ops::Mul<f64, Output = T>
        + std::ops::Add<Output = T>
        + std::ops::Sub<Output = T>,
{
    let rows = |m: &[[f64; 4]; 4]| {
        std::array::from_fn(|j| q[0] * m[j][0] + q[1] * m[j][1] + q[2] * m[j][2] + q[3] * m[j][3])
    };
    match basis {
        Basis::BSpline => q,
        Basis::Bezier => rows(&BEZIER_TO_BSPLINE),
        Basis::CatmullRom => rows(&CATMULL_ROM_TO_BSPLINE),
        Basis::Linear => linear(q[0], q[1]),
    }
}

/// The B-spline points of the straight segment a → b: (2a − b, a, b, 2b − a).
fn linear<T>(a: T, b: T) -> [T; 4]
where
    T: Copy + std::ops::Mul<f64, Output = T> + std::ops::Sub<Output = T>,
{
    [a * 2.0 - b, a, b, b * 2.0 - a]
}

/// Appends one curve's B-spline control points and, per segment, its first control point (relative to the
/// curve's first) to `cps` and `first`. `points` has a valid count for (`basis`, `wrap`) ([`segment_count`]), and a
/// `Radius::Vertex` one radius per point, a `Radius::Varying` [`varying_count`] radii. Returns how many control
/// point radii were below zero and clamped to 0.
pub fn convert(
    basis: Basis,
    wrap: Wrap,
    points: &[Vec3],
    radius: Radius<'_>,
    cps: &mut Vec<[f32; 4]>,
    first: &mut Vec<u32>,
) -> usize {
    let n = points.len();
    let segments = segment_count(basis, wrap, n).unwrap_or(0);
    let start = cps.len();
    let pts: Vec<DVec3> = with_phantoms(
        basis,
        wrap,
        &points.iter().map(|p| p.as_dvec3()).collect::<Vec<_>>(),
        |a, b| 2.0 * a - b,
    );
    let vertex_radius: Option<Vec<f64>> = match radius {
        Radius::Vertex(r) => Some(with_phantoms(
            basis,
            wrap,
            &r.iter().map(|&r| f64::from(r)).collect::<Vec<_>>(),
            |a, b| 2.0 * a - b,
        )),
        _ => None,
    };
    let cp = |p: DVec3, r: f64| [p.x as f32, p.y as f32, p.z as f32, r as f32];
    let shared = basis == Basis::BSpline && !matches!(radius, Radius::Varying(_));
    if shared {
        // The B-spline's own points, wrapped around for a closed curve; segment k starts at point k.
        let m = pts.len();
        let count = if wrap == Wrap::Periodic { m + 3 } else { m };
        for i in 0..count {
            let r = match (&vertex_radius, radius) {
                (Some(v), _) => v[i % m],
                (None, Radius::Constant(c)) => f64::from(c),
                _ => 0.0,
            };
            cps.push(cp(pts[i % m], r));
        }
        first.extend(0..segments as u32);
    } else {
        let nv = pts.len();
        for k in 0..segments {
            let idx = segment_vertices(basis, wrap, nv, k);
            let p = convert4(basis, idx.map(|i| pts[i]));
            let r: [f64; 4] = match (&vertex_radius, radius) {
                (Some(v), _) => convert4(basis, idx.map(|i| v[i])),
                (None, Radius::Varying(v)) => {
                    let next = if wrap == Wrap::Periodic && basis != Basis::Linear {
                        (k + 1) % segments
                    } else if basis == Basis::Linear {
                        idx[1]
                    } else {
                        k + 1
                    };
                    linear(f64::from(v[k]), f64::from(v[next]))
                }
                (None, Radius::Constant(c)) => [f64::from(c); 4],
                _ => [0.0; 4],
            };
            first.push((4 * k) as u32);
            for j in 0..4 {
                cps.push(cp(p[j], r[j]));
            }
        }
    }
    let mut clamped = 0;
    for c in &mut cps[start..] {
        if c[3] < 0.0 {
            c[3] = 0.0;
            clamped += 1;
        }
    }
    clamped
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hair::Strands;

    /// Direct evaluation of the file's basis on a segment's four points (no conversion): the reference.
    fn basis_at(basis: Basis, q: [f64; 4], u: f64) -> f64 {
        let (u2, u3) = (u * u, u * u * u);
        let t = 1.0 - u;
        match basis {
            Basis::Bezier => {
                t * t * t * q[0] + 3.0 * t * t * u * q[1] + 3.0 * t * u2 * q[2] + u3 * q[3]
            }
            Basis::CatmullRom => {
                0.5 * ((2.0 * q[1])
                    + (-q[0] + q[2]) * u
                    + (2.0 * q[0] - 5.0 * q[1] + 4.0 * q[2] - q[3]) * u2
                    + (-q[0] + 3.0 * q[1] - 3.0 * q[2] + q[3]) * u3)
            }
            Basis::BSpline => {
                (t * t * t * q[0]
                    + (3.0 * u3 - 6.0 * u2 + 4.0) * q[1]
                    + (-3.0 * u3 + 3.0 * u2 + 3.0 * u + 1.0) * q[2]
                    + u3 * q[3])
                    / 6.0
            }
            Basis::Linear => q[0] + (q[1] - q[0]) * u,
        }
    }

    /// The source indices of segment `k`, written out per case (independent of `segment_vertices`): into the
    /// vertices with phantoms at both ends for pinned B-spline and Catmull-Rom curves.
    fn reference_indices(basis: Basis, wrap: Wrap, n: usize, k: usize) -> [usize; 4] {
        match (basis, wrap) {
            (Basis::Linear, Wrap::Periodic) => [k, (k + 1) % n, 0, 0],
            (Basis::Linear, _) => [k, k + 1, 0, 0],
            (Basis::Bezier, Wrap::Periodic) => [3 * k, 3 * k + 1, 3 * k + 2, (3 * k + 3) % n],
            (Basis::Bezier, _) => [3 * k, 3 * k + 1, 3 * k + 2, 3 * k + 3],
            (_, Wrap::Periodic) => [k % n, (k + 1) % n, (k + 2) % n, (k + 3) % n],
            (_, _) => [k, k + 1, k + 2, k + 3],
        }
    }

    fn phantom(v: &[f64]) -> Vec<f64> {
        let n = v.len();
        let mut o = vec![2.0 * v[0] - v[1]];
        o.extend_from_slice(v);
        o.push(2.0 * v[n - 1] - v[n - 2]);
        o
    }

    const BASES: [Basis; 4] = [
        Basis::Bezier,
        Basis::BSpline,
        Basis::CatmullRom,
        Basis::Linear,
    ];
    const WRAPS: [Wrap; 3] = [Wrap::Nonperiodic, Wrap::Periodic, Wrap::Pinned];
    /// Parameters each segment is checked at.
    const US: [f32; 6] = [0.0, 0.125, 0.25, 0.5, 0.875, 1.0];
    /// Units in the last place of the largest control point the converted curve may be off by: the f64 → f32
    /// rounding of the points (½) and the f32 evaluation of four terms (about 4).
    const ULPS: f32 = 8.0;

    /// Every basis × wrap × width interpolation: the converted B-spline, evaluated as the tracers do, against the
    /// file's basis evaluated directly on the file's points and widths.
    #[test]
    fn every_basis_wrap_and_width_matches_the_curve_it_came_from() {
        // 7 points fit every kind (Bézier nonperiodic: 3k + 1; periodic needs a multiple of 3: 6).
        let all: Vec<Vec3> = (0..7)
            .map(|i| {
                let t = i as f32;
                Vec3::new(t, (0.7 * t).sin() * 2.0 + 0.25 * t * t, 1.0 - 0.5 * t)
            })
            .collect();
        // Widths that change slowly enough that no converted radius falls below 0 (and is clamped).
        let all_w: Vec<f32> = (0..7).map(|i| 0.2 + 0.003 * i as f32).collect();
        for basis in BASES {
            for wrap in WRAPS {
                let n = if basis == Basis::Bezier && wrap == Wrap::Periodic {
                    6
                } else {
                    7
                };
                let points = &all[..n];
                let segments = segment_count(basis, wrap, n).unwrap();
                let nvar = varying_count(basis, wrap, n, segments);
                let var_w: Vec<f32> = (0..nvar).map(|i| 0.1 + 0.002 * i as f32).collect();
                for which in ["constant", "vertex", "varying"] {
                    let radius = match which {
                        "constant" => Radius::Constant(0.15),
                        "vertex" => Radius::Vertex(&all_w[..n]),
                        _ => Radius::Varying(&var_w),
                    };
                    let (mut cps, mut first) = (Vec::new(), Vec::new());
                    assert_eq!(
                        convert(basis, wrap, points, radius, &mut cps, &mut first),
                        0
                    );
                    let mut s = Strands::default();
                    s.push_strand(&cps, &first, 1.0, [0.5; 3]).unwrap();
                    assert_eq!(s.segment_count(), segments, "{basis:?} {wrap:?}");
                    let scale = cps
                        .iter()
                        .flat_map(|c| c.iter().map(|x| x.abs()))
                        .fold(0.0f32, f32::max);
                    let tol = ULPS * scale * f32::EPSILON;
                    let coords: [Vec<f64>; 3] = std::array::from_fn(|a| {
                        let v: Vec<f64> = points.iter().map(|p| f64::from(p[a])).collect();
                        if phantoms(basis, wrap) {
                            phantom(&v)
                        } else {
                            v
                        }
                    });
                    let vw: Vec<f64> = all_w[..n].iter().map(|&w| f64::from(w)).collect();
                    let vw = if phantoms(basis, wrap) {
                        phantom(&vw)
                    } else {
                        vw
                    };
                    let nv = coords[0].len();
                    for k in 0..segments {
                        let idx = reference_indices(basis, wrap, nv, k);
                        for u in US {
                            let got = s.eval(k as u32, u);
                            let ud = f64::from(u);
                            let want = Vec3::from_array(std::array::from_fn(|a| {
                                basis_at(basis, idx.map(|i| coords[a][i]), ud) as f32
                            }));
                            let want_r = match which {
                                "constant" => 0.15,
                                "vertex" => basis_at(basis, idx.map(|i| vw[i]), ud) as f32,
                                _ => {
                                    let next = if basis == Basis::Linear {
                                        idx[1]
                                    } else if wrap == Wrap::Periodic {
                                        (k + 1) % segments
                                    } else {
                                        k + 1
                                    };
                                    let (a, b) = (f64::from(var_w[k]), f64::from(var_w[next]));
                                    (a + (b - a) * ud) as f32
                                }
                            };
                            let ctx = format!("{basis:?} {wrap:?} {which} segment {k} u {u}: got {got:?}, want {want} r {want_r}");
                            assert!((got.position - want).abs().max_element() <= tol, "{ctx}");
                            assert!((got.radius - want_r).abs() <= tol, "{ctx}");
                        }
                    }
                }
            }
        }
    }

    /// Values worked by hand: a Bézier segment starts on P₀ and ends on P₃; a Catmull-Rom segment runs from P₁ to
    /// P₂; a pinned curve starts on its first point; a closed curve's last segment ends where its first starts.
    #[test]
    fn end_points_land_where_each_basis_says() {
        let p = [
            Vec3::ZERO,
            Vec3::new(1.0, 2.0, 0.0),
            Vec3::new(3.0, 2.0, 0.0),
            Vec3::new(4.0, 0.0, 0.0),
        ];
        let run = |basis, wrap, pts: &[Vec3]| {
            let (mut cps, mut first) = (Vec::new(), Vec::new());
            convert(
                basis,
                wrap,
                pts,
                Radius::Constant(0.5),
                &mut cps,
                &mut first,
            );
            let mut s = Strands::default();
            s.push_strand(&cps, &first, 1.0, [0.5; 3]).unwrap();
            s
        };
        let bez = run(Basis::Bezier, Wrap::Nonperiodic, &p);
        assert_eq!(
            bez.control_points[0],
            [-1.0, -10.0, 0.0, 0.5],
            "6P0 - 7P1 + 2P2"
        );
        assert!((bez.eval(0, 0.0).position - p[0]).length() < 1e-6);
        assert!((bez.eval(0, 1.0).position - p[3]).length() < 1e-6);
        // Bézier midpoint: (P0 + 3P1 + 3P2 + P3)/8 = (2, 1.5, 0).
        assert!((bez.eval(0, 0.5).position - Vec3::new(2.0, 1.5, 0.0)).length() < 1e-6);
        let cr = run(Basis::CatmullRom, Wrap::Nonperiodic, &p);
        assert!((cr.eval(0, 0.0).position - p[1]).length() < 1e-6);
        assert!((cr.eval(0, 1.0).position - p[2]).length() < 1e-6);
        let pinned = run(Basis::CatmullRom, Wrap::Pinned, &p);
        assert_eq!(pinned.segment_count(), 3);
        assert!((pinned.eval(0, 0.0).position - p[0]).length() < 1e-6);
        assert!((pinned.eval(2, 1.0).position - p[3]).length() < 1e-6);
        let closed = run(Basis::BSpline, Wrap::Periodic, &p);
        assert_eq!(closed.segment_count(), 4);
        assert!((closed.eval(3, 1.0).position - closed.eval(0, 0.0).position).length() < 1e-6);
        let line = run(Basis::Linear, Wrap::Nonperiodic, &p[..2]);
        assert!((line.eval(0, 0.25).position - Vec3::new(0.25, 0.5, 0.0)).length() < 1e-6);
    }

    #[test]
    fn the_change_of_basis_matrices_are_m_b_inverse_times_m() {
        // M_B · C = M for both conversions, in exact f64 (every entry a small fraction).
        let m_b = [
            [-1.0, 3.0, -3.0, 1.0],
            [3.0, -6.0, 3.0, 0.0],
            [-3.0, 0.0, 3.0, 0.0],
            [1.0, 4.0, 1.0, 0.0],
        ]
        .map(|r: [f64; 4]| r.map(|x| x / 6.0));
        let m_z = [
            [-1.0, 3.0, -3.0, 1.0],
            [3.0, -6.0, 3.0, 0.0],
            [-3.0, 3.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
        ];
        let m_c = [
            [-1.0, 3.0, -3.0, 1.0],
            [2.0, -5.0, 4.0, -1.0],
            [-1.0, 0.0, 1.0, 0.0],
            [0.0, 2.0, 0.0, 0.0],
        ]
        .map(|r: [f64; 4]| r.map(|x| x / 2.0));
        for (c, m) in [(BEZIER_TO_BSPLINE, m_z), (CATMULL_ROM_TO_BSPLINE, m_c)] {
            for i in 0..4 {
                for j in 0..4 {
                    let v: f64 = (0..4).map(|k| m_b[i][k] * c[k][j]).sum();
                    assert!((v - m[i][j]).abs() < 1e-12, "{i} {j}: {v} vs {}", m[i][j]);
                }
            }
        }
    }

    #[test]
    fn segment_counts_follow_the_schema() {
        assert_eq!(segment_count(Basis::Bezier, Wrap::Nonperiodic, 7), Some(2));
        assert_eq!(segment_count(Basis::Bezier, Wrap::Nonperiodic, 6), None);
        assert_eq!(segment_count(Basis::Bezier, Wrap::Periodic, 6), Some(2));
        assert_eq!(segment_count(Basis::BSpline, Wrap::Nonperiodic, 3), None);
        assert_eq!(segment_count(Basis::BSpline, Wrap::Pinned, 2), Some(1));
        assert_eq!(segment_count(Basis::CatmullRom, Wrap::Periodic, 5), Some(5));
        assert_eq!(segment_count(Basis::Linear, Wrap::Periodic, 4), Some(4));
        assert_eq!(varying_count(Basis::BSpline, Wrap::Nonperiodic, 7, 4), 5);
        assert_eq!(varying_count(Basis::BSpline, Wrap::Periodic, 7, 7), 7);
    }
}
