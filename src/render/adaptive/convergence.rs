//! One pixel's running statistics ([`Convergence`]): Welford's mean and variance of its beauty, the aligned
//! halves and quarters the stop reads, the background flag and the predicted cost of its samples; what both rules
//! read, apart from the rules themselves.

use glam::Vec3;

/// Mean and variance accumulators of one pixel's beauty (Welford's update, in f64 for long runs).
#[derive(Debug, Clone, Copy, Default)]
pub struct Convergence {
    pub(super) n: u32,
    pub(super) mean: [f64; 3],
    pub(super) m2: [f64; 3],
    /// The largest sample per channel.
    pub(super) max: [f64; 3],
    /// Predicted CPU seconds of the pixel's samples ([`Schedule::cost`](super::Schedule::cost)), and how many samples
    /// they are.
    cost: f64,
    costed: u32,
    /// The sums per channel of the first P/2 and the first P samples, P the largest power of two ≤ n: the two
    /// halves of the pixel's first P samples ([`Convergence::split_rel_mse`]).
    halves: [[f32; 3]; 2],
    /// The sums per channel of the first P/4, P/2, 3P/4 and P samples (P ≥ 4): the pixel's first P samples in
    /// quarters, whose pairs measure the convergence one octave below the halves' ([`Convergence::split_terms`]).
    quarters: [[f32; 3]; 4],
    /// The sums per channel of the first 3·2ʲ samples, the latest such count reached: a later P = 2ʲ⁺² takes it as
    /// its 3P/4.
    at_three: [f32; 3],
    /// Samples added whose camera ray hit nothing (alpha 0; [`Convergence::add_uncovered`]).
    uncovered: u32,
    /// The share of the variance of the pixel's mean that reaches the image, when its samples are splatted over
    /// its neighbours ([`Convergence::splatted`]); `None`: the pixel is the mean of its own samples alone (share 1).
    share: Option<f32>,
}

impl Convergence {
    /// Adds one sample's beauty.
    #[inline]
    pub fn add(&mut self, beauty: Vec3) {
        self.n += 1;
        let k = f64::from(self.n);
        for (c, &x) in beauty.to_array().iter().enumerate() {
            let x = f64::from(x);
            let d = x - self.mean[c];
            self.mean[c] += d / k;
            self.m2[c] += d * (x - self.mean[c]);
            self.max[c] = if self.n == 1 { x } else { self.max[c].max(x) };
        }
        if self.n.is_power_of_two() {
            let sums = self.mean.map(|m| (m * k) as f32);
            if self.n >= 4 {
                // halves = [S(P/4), S(P/2)] until the shift below.
                self.quarters = [self.halves[0], self.halves[1], self.at_three, sums];
            }
            self.halves = [self.halves[1], sums];
        } else if self.n.is_multiple_of(3) && (self.n / 3).is_power_of_two() {
            self.at_three = self.mean.map(|m| (m * k) as f32);
        }
    }

    /// The relative MSE of the pixel's mean measured from its own samples' order: with P the largest power of two
    /// ≤ n, the means A and B of samples [0, P/2) and [P/2, P) give (A − B)² / 4 over (m² + 0.01), mean over RGB,
    /// times P / n; 0 with fewer than 2 samples. `means` are the denominators' m (as in
    /// [`Convergence::relative_variance_over`]).
    ///
    /// For any two exchangeable halves E[(A − B)²] / 4 = Var(P/2) − Var(P), the variance of the mean of P/2
    /// samples less that of P (Var(P) = (Var A + Cov) / 2, E[(A − B)²] = 2 (Var A − Cov)). Aligned blocks of an
    /// Owen-scrambled Sobol sequence are such halves, and the sampler converges no slower than independent samples
    /// (Var(P/2) ≥ 2 Var(P)), so this reads Var(P) or more: exactly it for independent samples, 1 + 2(ρ − 1) times
    /// it where the sampler's gain grows by ρ from P/2 to P samples. Unlike s² / n over a gain curve extrapolated
    /// from the pilots, it sees how much faster than independent samples *this* frame's samples converge at the
    /// counts they reached.
    pub fn split_rel_mse(&self, means: [f64; 3]) -> f64 {
        match self.split_terms(means) {
            Some(t) => t.halves * f64::from(t.p) / f64::from(self.n),
            None => 0.0,
        }
    }

    /// The pixel's halves and quarters as relative MSEs over `means` (mean over RGB, [`SplitTerms`]); `None` with
    /// fewer than 2 samples.
    pub(super) fn split_terms(&self, means: [f64; 3]) -> Option<SplitTerms> {
        if self.n < 2 {
            return None;
        }
        let p = 1u32 << (31 - self.n.leading_zeros());
        // Two adjacent blocks of `size` samples, from the running sums at their start, middle and end: (A − B)² / 4
        // over the denominators, mean over RGB.
        let pair = |start: [f32; 3], middle: [f32; 3], end: [f32; 3], size: u32| {
            let size = f64::from(size);
            let mut sum = 0.0;
            for c in 0..3 {
                let a = (f64::from(middle[c]) - f64::from(start[c])) / size;
                let b = (f64::from(end[c]) - f64::from(middle[c])) / size;
                sum += 0.25 * (a - b) * (a - b) / (means[c] * means[c] + 0.01);
            }
            sum / 3.0
        };
        let [first, both] = self.halves;
        let [s1, s2, s3, s4] = self.quarters;
        Some(SplitTerms {
            p,
            halves: pair([0.0; 3], first, both, p / 2),
            quarters: (p >= 4)
                .then(|| 0.5 * (pair([0.0; 3], s1, s2, p / 4) + pair(s2, s3, s4, p / 4))),
        })
    }

    /// Adds one sample's beauty, of a camera ray that hit nothing (the background alone: alpha 0).
    #[inline]
    pub fn add_uncovered(&mut self, beauty: Vec3) {
        self.add(beauty);
        self.uncovered += 1;
    }

    /// Whether the pixel has samples and every one of them was a camera ray that hit nothing: its samples differ
    /// only by where they fall in the pixel (the background seen through the pixel filter), with no light
    /// transport's noise, and a stratified sampler's convergence on them is much faster than on the pixels that
    /// see hair ([`Schedule::split_per_pixel`](super::Schedule::split_per_pixel)).
    pub fn background(&self) -> bool {
        self.n > 0 && self.uncovered == self.n
    }

    /// The pixel's samples are splatted and `share` of the variance of their mean reaches the image
    /// ([`SplatFilter::noise_shares`](crate::render::splat::SplatFilter::noise_shares)): what the stop reads of the
    /// pixel's own samples is scaled by it.
    pub fn splatted(&mut self, share: f32) {
        self.share = Some(share);
    }

    /// The share of the variance of the pixel's mean that reaches the image: 1 unless [`Convergence::splatted`].
    pub fn share(&self) -> f64 {
        self.share.map_or(1.0, f64::from)
    }

    /// Samples added.
    pub fn count(&self) -> u32 {
        self.n
    }

    /// Adds one sample's predicted cost in seconds (every sample taken, finite or not).
    #[inline]
    pub fn add_cost(&mut self, seconds: f64) {
        self.cost += seconds;
        self.costed += 1;
    }

    /// The pixel's mean predicted cost per sample, if its samples' costs were recorded.
    pub fn mean_cost(&self) -> Option<f64> {
        (self.costed > 0 && self.cost > 0.0).then(|| self.cost / f64::from(self.costed))
    }

    /// The estimated relative error of the pixel's mean (see the module docs), with the variance at its 95 % upper
    /// confidence bound. Infinite with fewer than 2 samples.
    pub fn relative_error(&self) -> f64 {
        if self.n < 2 {
            return f64::INFINITY;
        }
        let n = f64::from(self.n);
        let dof = n - 1.0;
        let upper = dof / chi2_lower_5(dof);
        let mut e2 = 0.0;
        for c in 0..3 {
            let s2 = self.m2[c] / dof;
            e2 += upper * s2 / n / (self.mean[c] * self.mean[c] + 0.01);
        }
        (e2 / 3.0).sqrt()
    }

    /// The per-sample relative variance over the denominators of `means` instead of the pixel's own: mean over RGB
    /// of s² / (m² + 0.01); 0 with fewer than 2 samples.
    pub fn relative_variance_over(&self, means: [f64; 3]) -> f64 {
        if self.n < 2 {
            return 0.0;
        }
        let dof = f64::from(self.n - 1);
        (0..3)
            .map(|c| self.m2[c] / dof / (means[c] * means[c] + 0.01))
            .sum::<f64>()
            / 3.0
    }

    /// The per-sample relative variance v = mean over RGB of s² / (x̄² + 0.01) (see the module docs); 0 with fewer
    /// than 2 samples.
    pub fn relative_variance(&self) -> f64 {
        if self.n < 2 {
            return 0.0;
        }
        let dof = f64::from(self.n - 1);
        let mut v = 0.0;
        for c in 0..3 {
            v += self.m2[c] / dof / (self.mean[c] * self.mean[c] + 0.01);
        }
        v / 3.0
    }
}

/// One pixel's aligned blocks compared, as relative MSEs ([`Convergence::split_terms`]): with P the largest power
/// of two ≤ n, `halves` = (A − B)² / 4 of the means of samples [0, P/2) and [P/2, P), whose expectation is
/// V(P/2) − V(P) (V(m) the variance of a mean of m samples), and `quarters` (P ≥ 4) the mean of the same over the
/// quarters' two pairs, V(P/4) − V(P/2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SplitTerms {
    /// P.
    pub(super) p: u32,
    /// V(P/2) − V(P), this pixel's one-pair estimate.
    pub(super) halves: f64,
    /// V(P/4) − V(P/2), the mean of two pairs; `None` below P = 4.
    pub(super) quarters: Option<f64>,
}

/// The 5 % quantile of χ² with `k` degrees of freedom (Wilson & Hilferty 1931: χ²/k is close to normal after a cube
/// root), floored so tiny k cannot make it 0.
pub(super) fn chi2_lower_5(k: f64) -> f64 {
    let z = 1.644_853_6;
    let a = 2.0 / (9.0 * k);
    (k * (1.0 - a - z * a.sqrt()).powi(3)).max(1e-3 * k)
}
