//! The subdivision and Newton search ([`Search`]): pieces pushed on a small stack, split until their bounds are
//! narrow, then Newton's iteration on (f, g) from each cylinder hit, in Embree's order so that both report the
//! same hit.

use glam::{Vec3, Vec4, Vec4Swizzles};

use super::super::CurveHit;
use super::bounds::{PieceBounds, SamplePoints};
use super::cylinder::{half_space, intersect_cylinder, sqr_point_to_line_distance, Interval};
use super::{BSpline, MAX_POINTS, NEWTON_ITERATIONS, STACK_SIZE, ULP};

/// Pieces of one level still to be refined: those in `valid` (bit i = piece i of [u0, u1]), front to back.
#[derive(Clone, Copy)]
pub(super) struct StackEntry {
    pub(super) valid: u8,
    pub(super) tlower: [f32; MAX_POINTS],
    pub(super) u0: f32,
    pub(super) u1: f32,
    pub(super) depth: u32,
}

/// The state of one ray–segment query: the curve in ray-relative coordinates and the closest hit so far.
pub(super) struct Search {
    pub(super) curve: BSpline,
    pub(super) dir: Vec3,
    /// t of the moved ray origin on the original ray.
    pub(super) dt: f32,
    pub(super) tnear: f32,
    /// Shrinks to the closest accepted hit.
    pub(super) tfar: f32,
    /// Error bound of a curve evaluation.
    pub(super) p_err: f32,
    pub(super) r_max: f32,
    pub(super) pieces: usize,
    pub(super) best: Option<CurveHit>,
    /// Stop at the first accepted hit.
    pub(super) any: bool,
}

/// Index of the smallest `values[i]` among the bits of `mask` (the lowest index on ties); `mask` is not empty.
pub(super) fn select_min(mask: u8, values: &[f32; MAX_POINTS]) -> usize {
    let mut best = usize::MAX;
    for i in 0..MAX_POINTS {
        if mask & (1 << i) != 0 && (best == usize::MAX || values[i] < values[best]) {
            best = i;
        }
    }
    best
}

impl Search {
    /// Steps 2–4 of the module docs over the whole segment, depth first, front to back.
    pub(super) fn run(&mut self, max_depth: u32) {
        let mut stack = [StackEntry {
            valid: 0,
            tlower: [0.0; MAX_POINTS],
            u0: 0.0,
            u1: 0.0,
            depth: 0,
        }; STACK_SIZE];
        let mut len = 0;
        let mut next = Some((0.0, 1.0, 1));
        loop {
            if self.any && self.best.is_some() {
                return;
            }
            let (u0, u1, depth) = match next.take() {
                Some(piece) => piece,
                None => {
                    // Pop the front-most piece still worth refining from the top entry.
                    if len == 0 {
                        return;
                    }
                    len -= 1;
                    let entry = &mut stack[len];
                    let mut valid = entry.valid;
                    for i in 0..self.pieces {
                        if entry.tlower[i] + self.dt > self.tfar {
                            valid &= !(1 << i);
                        }
                    }
                    if valid == 0 {
                        continue;
                    }
                    let i = select_min(valid, &entry.tlower);
                    valid &= !(1 << i);
                    entry.valid = valid;
                    let (u0, u1, depth) = (entry.u0, entry.u1, entry.depth);
                    if valid != 0 {
                        len += 1;
                    }
                    let step = 1.0 / self.pieces as f32;
                    (
                        lerp(u0, u1, i as f32 * step),
                        lerp(u0, u1, (i + 1) as f32 * step),
                        depth,
                    )
                }
            };
            if let Some(entry) = self.level(u0, u1, depth, max_depth) {
                assert!(len < STACK_SIZE, "round curve: subdivision stack overflow");
                stack[len] = entry;
                len += 1;
            }
        }
    }

    /// One subdivision level over [u0, u1]: bounds every piece, runs Newton on the pieces at the last level and
    /// returns those to refine.
    // One piece: it follows Embree's subdivision step for step, so that both report the same hits.
    pub(super) fn level(
        &mut self,
        u0: f32,
        u1: f32,
        depth: u32,
        max_depth: u32,
    ) -> Option<StackEntry> {
        let n = self.pieces;
        // Each piece as a Bézier curve: end points P0, P3 and handles P1 = P0 + P0′ h, P2 = P3 − P3′ h, where
        // h = (u1 − u0)/(3n) converts the B-spline derivative to the piece's Bézier handles.
        let dscale = (u1 - u0) * (1.0 / (3.0 * n as f32));
        let points = SamplePoints::new(&self.curve, u0, u1, n, dscale);
        let p: [Vec4; MAX_POINTS] = std::array::from_fn(|i| points.p(i));
        let dp: [Vec4; MAX_POINTS] = std::array::from_fn(|i| points.dp(i));
        let ray = Interval {
            lower: self.tnear - self.dt,
            upper: self.tfar - self.dt,
        };
        let bounds = points.bounds(self.dir, n, ray);
        let mut tp0 = [Interval::EMPTY; MAX_POINTS];
        let mut tp1 = [Interval::EMPTY; MAX_POINTS];
        let mut u_start = [[0.0f32; 2]; MAX_POINTS];
        let (mut newton0, mut newton1, mut refine0, mut refine1) = (0u8, 0u8, 0u8, 0u8);
        for i in 0..n {
            if cfg!(test) {
                self.check_bounds(&p, &dp, i, ray, &bounds);
            }
            if bounds.keep & (1 << i) == 0 {
                continue;
            }
            let (p0, p3, d0, d3) = (p[i], p[i + 1], dp[i], dp[i + 1]);
            let (p1, p2) = (p0 + d0, p3 - d3);
            // Bounding cylinders around the chord P0P3: the radius range widened by how far the handles stray.
            // The outer one, clipped by the ray extent and by the planes normal to the curve at the piece's ends,
            // is in `bounds`.
            let r_inner = ((p0.w.min(p1.w).min(p2.w).min(p3.w) - bounds.stray[i])
                * (1.0 - 2.0 * ULP))
                .max(0.0);
            let tp = Interval {
                lower: bounds.lower[i],
                upper: bounds.upper[i],
            };
            // Start parameters from the cylinder's axis parameter, as Embree maps it (over n + 1, not n).
            u_start[i] = [0, 1].map(|k| {
                let u = bounds.axis_u[k][i];
                lerp(u0, u1, (i as f32 + u.clamp(0.0, 1.0)) / (n + 1) as f32)
            });
            let inner = intersect_cylinder(self.dir, p0.xyz(), p3.xyz(), r_inner);
            let inner_t = inner.as_ref().map_or(Interval::EMPTY, |c| c.t);
            if self.any {
                if let Some(t) = self.inside_core(p0, p1, p2, p3, bounds.stray[i], ray) {
                    self.best = Some(CurveHit {
                        t: t + self.dt,
                        u: u_start[i][0],
                        v: 0.0,
                        ng: Vec3::ZERO,
                    });
                    return None;
                }
            }
            // Unstable where the ray misses the inner cylinder or meets it at a glancing angle (|d·Ng| < 0.3,
            // with Embree's unnormalised d and Ng): one more level there.
            let term_depth = |k: usize| {
                let unstable = inner
                    .as_ref()
                    .is_none_or(|c| self.dir.dot(c.ng[k]).abs() < 0.3);
                if unstable {
                    max_depth + 1
                } else {
                    max_depth
                }
            };
            // Front part: before the inner cylinder; back part: after it.
            let front = Interval {
                lower: tp.lower,
                upper: tp.upper.min(inner_t.lower),
            };
            // Closest-hit shortcut, for a front part that would be refined: a ray that reaches the piece's core at
            // t_core crossed the wall before it, in the front part (`inside_core`). Newton from the front part's
            // start, as at the last level; a root at or before t_core is that crossing, found without refining.
            // Otherwise the piece is refined as usual.
            if !self.any && !front.is_empty() && depth < term_depth(0) {
                if let Some(t_core) = self.inside_core(p0, p1, p2, p3, bounds.stray[i], ray) {
                    if let Some(hit) = self.solve(u_start[i][0], front.lower) {
                        if hit.t - self.dt <= t_core {
                            self.best = Some(hit);
                            self.tfar = hit.t;
                            continue;
                        }
                    }
                }
            }
            let back = Interval {
                lower: tp.lower.max(inner_t.upper),
                upper: tp.upper,
            };
            tp0[i] = front;
            tp1[i] = back;
            for (part, k, newton, refine) in [
                (front, 0, &mut newton0, &mut refine0),
                (back, 1, &mut newton1, &mut refine1),
            ] {
                if part.is_empty() {
                    continue;
                }
                if depth < term_depth(k) {
                    *refine |= 1 << i;
                } else {
                    *newton |= 1 << i;
                }
            }
        }
        let lower0 = tp0.map(|t| t.lower);
        let lower1 = tp1.map(|t| t.lower);
        // Newton from the front parts, front to back; each hit shortens tfar.
        while newton0 != 0 {
            let i = select_min(newton0, &lower0);
            newton0 &= !(1 << i);
            self.newton(u_start[i][0], tp0[i].lower);
            newton0 &= self.within_tfar(&lower0);
        }
        newton1 &= self.within_tfar(&lower1);
        // Then from the back parts, starting at the exit of the outer cylinder.
        while newton1 != 0 {
            let i = select_min(newton1, &lower1);
            newton1 &= !(1 << i);
            self.newton(u_start[i][1], tp1[i].upper);
            newton1 &= self.within_tfar(&lower1);
        }
        let refine0 = refine0 & self.within_tfar(&lower0);
        let refine1 = refine1 & self.within_tfar(&lower1);
        let valid = refine0 | refine1;
        (valid != 0).then(|| {
            let mut tlower = [0.0; MAX_POINTS];
            for i in 0..n {
                tlower[i] = if refine0 & (1 << i) != 0 {
                    lower0[i]
                } else {
                    lower1[i]
                };
            }
            StackEntry {
                valid,
                tlower,
                u0,
                u1,
                depth: depth + 1,
            }
        })
    }

    /// The scalar bounds of piece `i` (outer cylinder, cap planes, ray extent), one piece at a time: the unit
    /// tests assert that [`SamplePoints::bounds`] found them bit for bit.
    pub(super) fn check_bounds(
        &self,
        p: &[Vec4; MAX_POINTS],
        dp: &[Vec4; MAX_POINTS],
        i: usize,
        ray: Interval,
        bounds: &PieceBounds,
    ) {
        let keep = bounds.keep & (1 << i) != 0;
        let (p0, p3, d0, d3) = (p[i], p[i + 1], dp[i], dp[i + 1]);
        let (p1, p2) = (p0 + d0, p3 - d3);
        let chord = (p3 - p0).xyz();
        let stray = sqr_point_to_line_distance(d0.xyz(), chord)
            .max(sqr_point_to_line_distance(d3.xyz(), chord))
            .sqrt();
        let r_outer = (p0.w.max(p1.w).max(p2.w).max(p3.w) + stray) * (1.0 + 2.0 * ULP);
        let Some(outer) = intersect_cylinder(self.dir, p0.xyz(), p3.xyz(), r_outer) else {
            assert!(
                !keep,
                "SamplePoints::bounds kept piece {i} without outer cylinder"
            );
            return;
        };
        let tp = ray
            .intersect(outer.t)
            .intersect(half_space(self.dir, p0.xyz(), d0.xyz()))
            .intersect(half_space(self.dir, p3.xyz(), -d3.xyz()));
        assert_eq!(keep, !tp.is_empty(), "SamplePoints::bounds on piece {i}");
        if keep {
            let bits = |v: [f32; 5]| v.map(f32::to_bits);
            assert_eq!(
                bits([tp.lower, tp.upper, outer.u[0], outer.u[1], stray]),
                bits([
                    bounds.lower[i],
                    bounds.upper[i],
                    bounds.axis_u[0][i],
                    bounds.axis_u[1][i],
                    bounds.stray[i]
                ]),
                "SamplePoints::bounds on piece {i}"
            );
        }
    }

    /// The any-hit shortcut: the first t in `ray` at which the ray is inside the *core* of the Bézier piece
    /// `p0…p3` (x, y, z, r), if it gets there. The core is a cylinder around the chord p0p3, between the planes
    /// normal to the curve at the piece's ends, that the tube's wall cannot enter: a wall point is X = P(u) + r(u) n
    /// with n ⊥ P′(u), P(u) is within `stray` of the chord line, r(u) ≥ r_min (the least radius control value),
    /// and n's component across the line is at least cos θ, θ the largest angle between the chord and the curve's
    /// tangent (the tangent is a positive combination of the hodograph's control vectors p1 − p0, p2 − p1,
    /// p3 − p2, so θ is at most theirs). So the wall keeps r_min cos θ − stray from the line, and the core has that
    /// radius less the evaluation error. When stray is below it too, the axis runs inside the core, so the whole
    /// core is inside the tube; a ray that reaches it from outside crossed the tube's wall before — this
    /// segment's, or a neighbour's of the same strand through the shared end plane, or none when it came in
    /// through the strand's open root or tip (where Embree may see a miss). Shadow queries only ask whether
    /// a strand is hit, so they stop here, without refining or Newton.
    pub(super) fn inside_core(
        &self,
        p0: Vec4,
        p1: Vec4,
        p2: Vec4,
        p3: Vec4,
        stray: f32,
        ray: Interval,
    ) -> Option<f32> {
        let chord = (p3 - p0).xyz();
        let chord_len = chord.length();
        let cos_theta = [p1 - p0, p2 - p1, p3 - p2]
            .map(|v| v.xyz().dot(chord) / (v.xyz().length() * chord_len))
            .into_iter()
            .fold(1.0f32, f32::min);
        let r_min = p0.w.min(p1.w).min(p2.w).min(p3.w);
        let radius = r_min * cos_theta - stray - 4.0 * self.p_err;
        // NaN (a degenerate chord or handle) fails the test too.
        if !(cos_theta > 0.0 && stray < radius) {
            return None;
        }
        let core = intersect_cylinder(self.dir, p0.xyz(), p3.xyz(), radius)?;
        let inside = ray
            .intersect(core.t)
            .intersect(half_space(self.dir, p0.xyz(), (p1 - p0).xyz()))
            .intersect(half_space(self.dir, p3.xyz(), (p3 - p2).xyz() * -1.0));
        (!inside.is_empty()).then_some(inside.lower)
    }

    /// The pieces whose part starts no later than the closest hit so far.
    pub(super) fn within_tfar(&self, lower: &[f32; MAX_POINTS]) -> u8 {
        let mut mask = 0;
        for (i, &l) in lower.iter().enumerate() {
            if l + self.dt <= self.tfar {
                mask |= 1 << i;
            }
        }
        mask
    }

    /// Newton iterations on (u, t) for f = g = 0 (module docs) from (`u`, `t`), t relative to the moved origin.
    /// Records the hit and shortens tfar when a root in range is found.
    pub(super) fn newton(&mut self, u: f32, t: f32) {
        if self.any && self.best.is_some() {
            return;
        }
        if let Some(hit) = self.solve(u, t) {
            self.best = Some(hit);
            self.tfar = hit.t;
        }
    }

    /// The Newton iterations of [`Search::newton`] without recording: the root they converge to from (`u`, `t`),
    /// if it lies in [tnear, tfar] with u ∈ [0, 1].
    pub(super) fn solve(&self, mut u: f32, mut t: f32) -> Option<CurveHit> {
        let dir = self.dir;
        let dir_len = dir.length();
        for _ in 0..NEWTON_ITERATIONS {
            // Q(t) = t d (the origin is 0), R = Q − P(u).
            let q = t * dir;
            let q_err = 16.0 * ULP * dir_len * t;
            let (p, dpdu, ddpdu) = (
                self.curve.eval(u),
                self.curve.eval_du(u),
                self.curve.eval_dudu(u),
            );
            let r = q - p.xyz();
            let len_r = r.length();
            let r_err = q_err.max(self.p_err);
            let (drdu, drdt) = (-dpdu.xyz(), dir);
            // T = P′/|P′| and dT/du = (P″ |P′|² − P′ (P′·P″)) / |P′|³.
            let (d1, d2) = (dpdu.xyz(), ddpdu.xyz());
            let tangent = d1.normalize();
            let d11 = d1.dot(d1);
            let dtdu = (d2 * d11 - d1 * d1.dot(d2)) * (d11 * d11.sqrt()).recip();
            let cos_err = self.p_err / d1.length();
            // f = R·T, with its float error bound (Embree's estimate).
            let f = r.dot(tangent);
            let f_err = len_r * self.p_err + r_err + cos_err * (1.0 + len_r);
            let dfdu = drdu.dot(tangent) + r.dot(dtdu);
            let dfdt = drdt.dot(tangent);
            // K = |R|² − f² is the squared distance from the axis; g = sqrt(K) − r(u).
            let k = r.dot(r) - f * f;
            let dkdu = r.dot(drdu) - f * dfdu;
            let dkdt = r.dot(drdt) - f * dfdt;
            let rsqrt_k = 1.0 / k.sqrt();
            let g = k.sqrt() - p.w;
            let g_err = r_err + f_err + 16.0 * ULP * self.r_max;
            let dgdu = dkdu * rsqrt_k - dpdu.w;
            let dgdt = dkdt * rsqrt_k;
            // Newton step: J (Δu, Δt) = (f, g), J = [[∂f/∂u, ∂f/∂t], [∂g/∂u, ∂g/∂t]].
            let det = dfdu * dgdt - dfdt * dgdu;
            let rcp_det = 1.0 / det;
            let du = (dgdt * f - dfdt * g) * rcp_det;
            let dtt = (-dgdu * f + dfdu * g) * rcp_det;
            u -= du;
            t -= dtt;
            if f.abs() < f_err && g.abs() < g_err {
                let t_hit = t + self.dt;
                // Written so that NaNs are rejected.
                if !((self.tnear..=self.tfar).contains(&t_hit) && (0.0..=1.0).contains(&u)) {
                    return None;
                }
                // Ng = (P′ × R̂) × (P′ + r′ R̂): outward, tilted by the taper.
                let r_hat = (q - p.xyz()).normalize();
                let along = d1 + dpdu.w * r_hat;
                let around = d1.cross(r_hat);
                return Some(CurveHit {
                    t: t_hit,
                    u,
                    v: 0.0,
                    ng: around.cross(along),
                });
            }
        }
        None
    }
}

pub(super) fn lerp(a: f32, b: f32, s: f32) -> f32 {
    (1.0 - s) * a + s * b
}
