//! Gaussian lobes, the error function, and exact sampling of a truncated Gaussian.
//!
//! - [`gaussian`]: the normalised Gaussian g(β, x) of Hery & Ramamoorthi 2012 (thesis eq. 5), ∫ g dx = 1.
//! - [`gaussian_unit`]: the unit-height Gaussian of Sadeghi et al. 2010 / Ou et al. 2012 (thesis eq. 16),
//!   e^{−x²/2β²}; ∫ = β√(2π), so it is **not** a pdf.
//! - [`erfc`], [`erf`], [`erfc_inv`]: f64 arithmetic, relative accuracy 1.2e-7 (the f32 pdfs' own precision)
//!   out to the underflow of e^{−x²}: the truncated Gaussian needs relative accuracy in its tails.
//! - [`normal_quantile`]: Φ⁻¹ by Wichura's AS 241, relative accuracy ~1e-16 with no exponential (at most one
//!   logarithm): the inverse CDF of the samplers.
//! - [`TruncatedGaussian`]: sampling by inverse CDF and the matching pdf, in f64 (Kajiya-Kay's cone sampler).
//! - [`TruncatedGaussianF32`]: the same distribution with its normalisation in f32, the sampler and pdf of
//!   [`super::Sampling::ExactPdf`] for the Marschner lobes (Ou et al. 2012, appendix A: the Box-Muller sampler
//!   with clamping has no consistent pdf; truncating and renormalising the Gaussian does).
//!
//! erfc and Φ⁻¹ stay hand-written rather than from `statrs`: they are on the samplers' measured hot path.

use crate::util::real::{Real, RealMask};
use std::f64::consts::{FRAC_1_SQRT_2, SQRT_2};

/// 1/√(2π).
pub const INV_SQRT_TAU: f32 = 0.398_942_3;

/// e^x for the (non-positive) exponents of Gaussian lobes: exactly `x.exp()`, but 0 below −104, where e^x is 0 in
/// f32 anyway, without going through libm's underflow path (which sets errno and showed in the eval profiles:
/// narrow lobes underflow for most directions).
#[inline]
pub fn exp_lobe(x: f32) -> f32 {
    if x < -104.0 {
        0.0
    } else {
        x.exp()
    }
}

/// Normalised Gaussian with standard deviation `beta` (> 0) at `x` (thesis eq. 5's g): e^{−x²/2β²} / (β√(2π)).
#[inline]
pub fn gaussian(beta: f32, x: f32) -> f32 {
    // x/β first: β² would underflow long before x/β overflows.
    let z = x / beta;
    exp_lobe(-0.5 * z * z) * INV_SQRT_TAU / beta
}

/// Unit-height Gaussian (thesis eq. 16, Sadeghi et al. 2010): e^{−x²/2β²}. Peak 1 at x = 0; integral β√(2π).
#[inline]
pub fn gaussian_unit(beta: f32, x: f32) -> f32 {
    exp_lobe(gaussian_exponent(beta, x))
}

/// The exponent −x²/2β² of [`gaussian_unit`], for products of Gaussians taken as one exponential.
#[inline]
pub fn gaussian_exponent(beta: f32, x: f32) -> f32 {
    let z = x / beta;
    -0.5 * z * z
}

/// ∫_lo^hi e^{−x²/2β²} dx = β √(π/2) (erf(hi/β√2) − erf(lo/β√2)).
pub fn gaussian_unit_integral(beta: f32, lo: f32, hi: f32) -> f32 {
    let s = beta as f64 * SQRT_2;
    (beta as f64 * (std::f64::consts::PI / 2.0).sqrt() * (erf(hi as f64 / s) - erf(lo as f64 / s)))
        as f32
}

/// The coefficients of P in Press et al.'s erfc fit (Numerical Recipes in C 2nd ed. §6.2, `erfcc`), shared by
/// [`erfc_nonneg`] (f64) and [`erfc_parts`] (f32).
const ERFCC: [f64; 10] = [
    -1.265_512_23,
    1.000_023_68,
    0.374_091_96,
    0.096_784_18,
    -0.186_288_06,
    0.278_868_07,
    -1.135_203_98,
    1.488_515_87,
    -0.822_152_23,
    0.170_872_77,
];

/// erfc(z) for z ≥ 0: the Chebyshev-derived fit of Press et al., Numerical Recipes in C 2nd ed. §6.2 (`erfcc`),
/// erfc z = t·exp(−z² + P(t)) with t = 1/(1 + z/2) and P of degree 9; fractional error < 1.2e-7 for every z ≥ 0,
/// tails included. That matches the f32 pdfs the models return, and a degree-9 polynomial is three times cheaper
/// than a double-precision fit (the models evaluate it several times per sample). P is evaluated by Estrin's
/// scheme (pairs, then t², t⁴, t⁸), not Horner: the same polynomial with a dependency chain of four
/// multiply-adds instead of nine, which is what the samplers wait on.
#[inline]
fn erfc_nonneg(z: f64) -> f64 {
    const C: [f64; 10] = ERFCC;
    let t = 1.0 / (1.0 + 0.5 * z);
    let (t2, t4) = (t * t, (t * t) * (t * t));
    let p01 = C[0] + C[1] * t;
    let p23 = C[2] + C[3] * t;
    let p45 = C[4] + C[5] * t;
    let p67 = C[6] + C[7] * t;
    let p89 = C[8] + C[9] * t;
    let p = (p01 + t2 * p23) + t4 * ((p45 + t2 * p67) + t4 * p89);
    t * (-z * z + p).exp()
}

/// The complementary error function erfc(x) = 1 − erf(x), relative accuracy 1.2e-7 for every x ≥ 0 (0 past
/// x ≈ 26.5, where it underflows); for x < 0, 2 − erfc(−x).
#[inline]
pub fn erfc(x: f64) -> f64 {
    if x >= 0.0 {
        erfc_nonneg(x)
    } else {
        2.0 - erfc_nonneg(-x)
    }
}

/// The error function erf(x).
#[inline]
pub fn erf(x: f64) -> f64 {
    if x.abs() < 0.5 {
        // Near 0, 1 − erfc would keep only erfc's absolute accuracy; the Maclaurin series
        // 2/√π Σ (−1)ⁿ x^{2n+1} / (n!(2n+1)) is exact to rounding after 10 terms for |x| < 1/2.
        let x2 = x * x;
        let (mut term, mut sum) = (x, x);
        for n in 1..11 {
            term *= -x2 / n as f64;
            sum += term / (2 * n + 1) as f64;
        }
        return std::f64::consts::FRAC_2_SQRT_PI * sum;
    }
    if x >= 0.0 {
        1.0 - erfc_nonneg(x)
    } else {
        erfc_nonneg(-x) - 1.0
    }
}

/// The inverse of [`erfc`]: x with erfc(x) = p, p ∈ (0, 2). Out of range: ±100 (beyond every double's erfc).
/// Initial guess: Abramowitz & Stegun 26.2.23's rational approximation of the normal quantile; then two Halley
/// steps on [`erfc`] itself, each cubically convergent, so erfc(erfc_inv(p)) = p to rounding (the sampler is the
/// exact inverse of the CDF the pdf normalises with, whatever erfc's own error).
pub fn erfc_inv(p: f64) -> f64 {
    if p >= 2.0 {
        return -100.0;
    }
    if p <= 0.0 || p.is_nan() {
        return 100.0;
    }
    let pp = if p < 1.0 { p } else { 2.0 - p };
    let t = (-2.0 * (pp / 2.0).ln()).sqrt();
    let mut x =
        -FRAC_1_SQRT_2 * ((2.30753 + t * 0.27061) / (1.0 + t * (0.99229 + t * 0.04481)) - t);
    for _ in 0..2 {
        // Halley: f = erfc(x) − pp, f' = −2/√π e^{−x²}, f''/f' = −2x.
        let err = erfc_nonneg(x) - pp;
        x += err / (std::f64::consts::FRAC_2_SQRT_PI * (-x * x).exp() - x * err);
    }
    if p < 1.0 {
        x
    } else {
        -x
    }
}

/// The standard normal CDF Φ(x) = ½ erfc(−x/√2).
#[inline]
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * erfc(-x * FRAC_1_SQRT_2)
}

/// Φ⁻¹(p), the standard normal quantile, for p ∈ (0, 1): Wichura 1988, "Algorithm AS 241: the percentage points
/// of the normal distribution" (Applied Statistics 37(3), 477–484), `PPND16`: a rational function of degree 7/7
/// in (p − ½)² for |p − ½| ≤ 0.425, else in r = √(−ln min(p, 1 − p)) (two pieces, split at r = 5). Relative
/// accuracy about 1e-16 down to p ~ 1e-300, with one logarithm in the tails and no exponential: three times
/// cheaper than Halley steps on [`erfc`]. p ≤ 0 gives −∞ and p ≥ 1 gives +∞ (callers clamp).
// The coefficients are AS 241's 20-digit ones as published, kept verbatim so they can be checked against it.
#[allow(clippy::excessive_precision)]
#[inline]
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 8] = [
        3.387_132_872_796_366_608,
        1.331_416_678_917_843_774_5e2,
        1.971_590_950_306_551_442_7e3,
        1.373_169_376_550_946_112_5e4,
        4.592_195_393_154_987_145_7e4,
        6.726_577_092_700_870_085_3e4,
        3.343_057_558_358_812_810_5e4,
        2.509_080_928_730_122_672_7e3,
    ];
    const B: [f64; 8] = [
        1.0,
        4.231_333_070_160_091_125_2e1,
        6.871_870_074_920_579_083e2,
        5.394_196_021_424_751_107_7e3,
        2.121_379_430_158_659_586_7e4,
        3.930_789_580_009_271_061e4,
        2.872_908_573_572_194_267_4e4,
        5.226_495_278_852_854_561e3,
    ];
    const C: [f64; 8] = [
        1.423_437_110_749_683_577_34,
        4.630_337_846_156_545_295_9,
        5.769_497_221_460_691_405_5,
        3.647_848_324_763_204_605_04,
        1.270_458_252_452_368_382_58,
        2.417_807_251_774_506_117_7e-1,
        2.272_384_498_926_918_458_33e-2,
        7.745_450_142_783_414_076_4e-4,
    ];
    const D: [f64; 8] = [
        1.0,
        2.053_191_626_637_758_821_87,
        1.676_384_830_183_803_849_4,
        6.897_673_349_851_000_045_5e-1,
        1.481_039_764_274_800_745_9e-1,
        1.519_866_656_361_645_719_66e-2,
        5.475_938_084_995_344_946e-4,
        1.050_750_071_644_416_843_24e-9,
    ];
    const E: [f64; 8] = [
        6.657_904_643_501_103_777_2,
        5.463_784_911_164_114_369_9,
        1.784_826_539_917_291_335_8,
        2.965_605_718_285_048_912_3e-1,
        2.653_218_952_657_612_309_3e-2,
        1.242_660_947_388_078_438_6e-3,
        2.711_555_568_743_487_578_15e-5,
        2.010_334_399_292_288_132_65e-7,
    ];
    const F: [f64; 8] = [
        1.0,
        5.998_322_065_558_879_376_9e-1,
        1.369_298_809_227_358_053_1e-1,
        1.487_536_129_085_061_485_25e-2,
        7.868_691_311_456_132_591e-4,
        1.846_318_317_510_054_681_8e-5,
        1.421_511_758_316_445_888_7e-7,
        2.044_263_103_389_939_785_64e-15,
    ];
    // Σ c_k r^k, k = 0..7, by Estrin's scheme (a shorter dependency chain than Horner; see `erfc_nonneg`).
    let poly = |c: &[f64; 8], r: f64| {
        let r2 = r * r;
        (c[0] + c[1] * r)
            + r2 * (c[2] + c[3] * r)
            + (r2 * r2) * ((c[4] + c[5] * r) + r2 * (c[6] + c[7] * r))
    };
    let ratio = |num: &[f64; 8], den: &[f64; 8], r: f64| poly(num, r) / poly(den, r);
    let q = p - 0.5;
    if q.abs() <= 0.425 {
        return q * ratio(&A, &B, 0.180_625 - q * q);
    }
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    let r = (-(if q < 0.0 { p } else { 1.0 - p }).ln()).sqrt();
    let x = if r <= 5.0 {
        ratio(&C, &D, r - 1.6)
    } else {
        ratio(&E, &F, r - 5.0)
    };
    if q < 0.0 {
        -x
    } else {
        x
    }
}

/// (t, P(t)) of [`erfc_nonneg`]'s fit in f32, erfc z = t·e^{−z² + P(t)} for z ≥ 0 (Press et al. §6.2): the scaled
/// complementary error function e^{z²} erfc z = t·e^{P(t)} without its exponential, so that callers can fold
/// e^{−z²} into a ratio of tails that would each underflow f32. Generic over the number type ([`Real`]): one z
/// per lane, the same arithmetic in each.
#[inline]
pub fn erfc_parts<R: Real>(z: R) -> (R, R) {
    // The same coefficients, each rounded to the nearest f32.
    const C: [f32; 10] = {
        let mut c = [0.0f32; 10];
        let mut i = 0;
        while i < 10 {
            c[i] = ERFCC[i] as f32;
            i += 1;
        }
        c
    };
    let c = |k: usize| R::splat(C[k]);
    let t = R::splat(1.0) / (R::splat(1.0) + R::splat(0.5) * z);
    let (t2, t4) = (t * t, (t * t) * (t * t));
    let p01 = c(0) + c(1) * t;
    let p23 = c(2) + c(3) * t;
    let p45 = c(4) + c(5) * t;
    let p67 = c(6) + c(7) * t;
    let p89 = c(8) + c(9) * t;
    (t, (p01 + t2 * p23) + t4 * ((p45 + t2 * p67) + t4 * p89))
}

/// ½ erfc(s) for s ≥ 0 in f32 arithmetic ([`erfc_parts`]; relative accuracy ~1.2e-7 plus f32 rounding), per lane.
#[inline(always)]
fn half_erfc<R: Real>(s: R) -> R {
    let (t, p) = erfc_parts(s);
    R::splat(0.5) * t * (-s * s + p).exp()
}

/// ½ erfc(z/√2) = Φ(−z) for z ≥ 0 in f32, 0 beyond `NEGLIGIBLE_TAIL` (as [`TruncatedGaussian::new`] drops it).
#[inline]
fn upper_tail_f32(z: f64) -> f32 {
    if z > NEGLIGIBLE_TAIL {
        return 0.0;
    }
    half_erfc((z * FRAC_1_SQRT_2) as f32)
}

/// A [`TruncatedGaussian`] whose normalisation is taken in f32, for densities that are f32 anyway: the θh
/// distributions of Marschner's lobes, built afresh for every view direction (the interval moves with θr), where
/// the f64 constructor's two double exponentials would be the largest single cost of a sample.
///
/// The standardised ends and points are formed in f64 as [`TruncatedGaussian::new`] forms them (they cancel for
/// narrow lobes; f64 subtraction and multiplication cost nothing), the error functions in f32 (`erfc_parts`,
/// the same fit). Three cases:
///
/// - **Central** (the interval contains the mean; after mirroring so that a ≤ 0, b > 0): tails Φ(a) and 1 − Φ(b)
///   (0 beyond `NEGLIGIBLE_TAIL`, as the f64 type), Z = 1 − Φ(a) − (1 − Φ(b)). The interval is at least σ wide
///   for the models' ranges (π/2 wide, β ≤ π/2), so Z ≥ 0.38 and does not cancel. pdf = e^{−x²/2}/(σ√(2π) Z);
///   [`TruncatedGaussianF32::sample`] inverts the CDF with these same f32 tails and Z, so it draws exactly the
///   density `pdf` returns (up to the rounding of its arguments), and within ~1e-6 of the f64 type's (tested).
/// - **Tail** (b ≤ 0: the whole interval on one side of the mean): Z = ½ e^{−b²/2} [T(|b|/√2) − T(|a|/√2)
///   e^{−(a² − b²)/2}], with T(z) = e^{z²} erfc z = t e^{P(t)}, and the density's e^{−x²/2} taken as one
///   exponential of −(x² − b²)/2 ≥ 0: nothing underflows however far the interval is from the mean. Sampling
///   builds the f64 [`TruncatedGaussian`] (rare: a lobe whose shift puts it outside the view's θh range).
/// - **Uniform**: the f64 type's fallback (mass ≤ 1e-300), reproduced from ln of the same mass.
///
/// Relative error of the pdf < 1e-6 against the f64 type (tested), up to the f32 rounding of the exponent where
/// the density is e^{−20} below its maximum.
#[derive(Debug, Clone, Copy)]
pub struct TruncatedGaussianF32 {
    mu: f64,
    sigma: f64,
    inv_sigma: f64,
    lo: f64,
    hi: f64,
    /// Standardised and, if `flip`, mirrored ends: the variable s·(y − μ)/σ ∈ [a, b] with a ≤ 0.
    a: f64,
    b: f64,
    flip: bool,
    /// 1/(σ√(2π)).
    norm: f32,
    mass: Mass,
}

/// The normalisation of a [`TruncatedGaussianF32`] (see its docs for the three cases).
#[derive(Debug, Clone, Copy)]
enum Mass {
    /// Φ(a), 1 − Φ(b) and Z.
    Central { p_a: f32, p_b: f32, z: f64 },
    /// P(t_b) and the scaled mass Z e^{b²/2 − P(t_b)}.
    Tail { p_b: f32, scaled: f32 },
    /// 1/(hi − lo).
    Uniform(f32),
}

impl TruncatedGaussianF32 {
    /// N(`mu`, `sigma`²) on [`lo`, `hi`]; `inv_sigma` = 1/`sigma` (callers keep both: no division here).
    #[inline(always)]
    pub fn new(mu: f64, sigma: f64, inv_sigma: f64, lo: f64, hi: f64) -> TruncatedGaussianF32 {
        let (mut a, mut b) = ((lo - mu) * inv_sigma, (hi - mu) * inv_sigma);
        let flip = a > 0.0;
        if flip {
            (a, b) = (-b, -a);
        }
        let mass = if b > 0.0 {
            let (p_a, p_b) = (upper_tail_f32(-a), upper_tail_f32(b));
            // In f64, so that p_a + Z + p_b = 1 to rounding: the sampler's two halves then meet at the median.
            let z = 1.0 - p_a as f64 - p_b as f64;
            Mass::Central { p_a, p_b, z }
        } else {
            let (tb, pb) = erfc_parts((-b * FRAC_1_SQRT_2) as f32);
            // (a² − b²)/2 ≥ 0: the lower end's tail relative to the upper end's; e^{−40} is below f32's resolution.
            let d = (0.5 * (a - b) * (a + b)) as f32;
            let ratio = if d > 40.0 {
                0.0
            } else {
                let (ta, pa) = erfc_parts((-a * FRAC_1_SQRT_2) as f32);
                ta / tb * (pa - pb - d).exp()
            };
            let scaled = 0.5 * tb * (1.0 - ratio);
            // Mass = scaled · e^{−b²/2 + P(t_b)}: below 1e-300 (ln = −690.8) the f64 type is uniform.
            if b < -36.0 && (-0.5 * b * b) as f32 + pb + scaled.ln() <= -690.775_5 {
                Mass::Uniform((1.0 / (hi - lo)) as f32)
            } else {
                Mass::Tail { p_b: pb, scaled }
            }
        };
        TruncatedGaussianF32 {
            mu,
            sigma,
            inv_sigma,
            lo,
            hi,
            a,
            b,
            flip,
            norm: INV_SQRT_TAU * inv_sigma as f32,
            mass,
        }
    }

    /// The standardised point x = (y − μ)/σ (unmirrored).
    #[inline]
    fn standardise(&self, y: f64) -> f64 {
        (y - self.mu) * self.inv_sigma
    }

    /// The untruncated normal density at standardised `x`, e^{−x²/2}/(σ√(2π)) in f32, which
    /// [`TruncatedGaussianF32::pdf`] hands to [`TruncatedGaussianF32::pdf_given`]. (A caller that has it already,
    /// Marschner's M with its own 1/(β√(2π)), calls `pdf_given` directly: one exponential for both.)
    #[inline]
    fn gaussian(&self, x: f64) -> f32 {
        self.norm * exp_lobe(-0.5 * (x * x) as f32)
    }

    /// The density at `y` (0 outside [lo, hi]), given `g` = e^{−x²/2}/(σ√(2π)) at its
    /// standardised point `x`: g/Z in the central case; the tail case recomputes its own exponential (g would
    /// underflow there).
    #[inline]
    pub fn pdf_given(&self, y: f64, x: f64, g: f32) -> f32 {
        if !(self.lo..=self.hi).contains(&y) {
            return 0.0;
        }
        match self.mass {
            Mass::Central { z, .. } => g / z as f32,
            Mass::Tail { p_b, scaled } => {
                let x = if self.flip { -x } else { x };
                let e = (0.5 * (x - self.b) * (x + self.b)) as f32;
                self.norm * (-e - p_b).exp() / scaled
            }
            Mass::Uniform(density) => density,
        }
    }

    /// The density at `y` (0 outside [lo, hi]).
    #[inline]
    pub fn pdf(&self, y: f64) -> f32 {
        let x = self.standardise(y);
        let g = match self.mass {
            Mass::Central { .. } => self.gaussian(x),
            _ => 0.0,
        };
        self.pdf_given(y, x, g)
    }

    /// The value at CDF level `u` ∈ [0, 1]. Central case: as [`TruncatedGaussian::sample`], Φ⁻¹ of the lower-tail
    /// level p_a + uZ below the median and −Φ⁻¹ of the upper-tail level p_b + (1 − u)Z above it, with this
    /// type's own f32 tails and Z, so that the density drawn is the one [`TruncatedGaussianF32::pdf`] returns.
    /// Otherwise the f64 [`TruncatedGaussian`] draws (the two agree to ~1e-6).
    #[inline]
    pub fn sample(&self, u: f64) -> f64 {
        let Mass::Central { p_a, p_b, z, .. } = self.mass else {
            return TruncatedGaussian::new(self.mu, self.sigma, self.lo, self.hi).sample(u);
        };
        let x = standardised_inverse_cdf(u, self.flip, p_a as f64, z, p_b as f64, self.a, self.b);
        (self.mu + self.sigma * x).clamp(self.lo, self.hi)
    }
}

/// The inverse CDF both truncated Gaussians share, in standardised units: the normal restricted to [a, b] (a ≤ 0;
/// mirrored from [−b, −a] if `flip`), with lower tail `p_a` = Φ(a), mass `z`, and `p_b` = 1 − Φ(b) if b > 0
/// (Φ(b) otherwise, unused), at CDF level `u`. Returns the unmirrored standardised value.
#[inline]
fn standardised_inverse_cdf(u: f64, flip: bool, p_a: f64, z: f64, p_b: f64, a: f64, b: f64) -> f64 {
    // Mirrored: the CDF runs the other way, so the value stays increasing in u.
    let u = if flip { 1.0 - u } else { u };
    let t = p_a + u * z;
    let x = if b <= 0.0 || t <= 0.5 {
        // Lower half: Φ⁻¹(t), accurate for tiny t. (Φ⁻¹ is exact to ~1e-16 while p_a and Z carry erfc's
        // 1.2e-7: the drawn density is φ/Z, what pdf() returns, inside (a, b); only an atom of relative size
        // ~1e-7 · p_a/Z can pile up at an end, from the clamp below.)
        normal_quantile(t)
    } else {
        // Upper half: work with the upper tail 1 − t = (1 − Φ(b)) + (1 − u) Z.
        -normal_quantile(p_b + (1.0 - u) * z)
    };
    let x = x.clamp(a, b);
    if flip {
        -x
    } else {
        x
    }
}

/// Standardised distance beyond which a tail of the normal is dropped from a [`TruncatedGaussian`] whose interval
/// contains the mean: Φ(−6) = 9.9e-10, so the mass (≥ ½ there) changes by less than 4e-9 relative, 1/15 of an
/// f32 ulp, and the erfc (one exponential) of that end is skipped.
const NEGLIGIBLE_TAIL: f64 = 6.0;

/// A normal distribution N(μ, σ²) restricted to [lo, hi] and renormalised, sampled by inverse CDF.
///
/// [`TruncatedGaussian::sample`] and [`TruncatedGaussian::pdf`] describe the same density to rounding, also far
/// in the tails (the interval may lie tens of σ from μ): tail probabilities are carried as erfc of the nearer
/// side, never as 1 − Φ. If the interval's mass underflows a double (more than ~37σ from μ), the distribution
/// falls back to uniform on [lo, hi], in both methods alike. When the interval contains μ, a tail beyond
/// `NEGLIGIBLE_TAIL` σ is taken as 0 by both methods alike: the interval is then in effect extended to ±∞ on
/// that side, a change of < 1e-9 in probability, far below the f32 pdfs' resolution.
#[derive(Debug, Clone, Copy)]
pub struct TruncatedGaussian {
    mu: f64,
    sigma: f64,
    lo: f64,
    hi: f64,
    /// Standardised and, if `flip`, mirrored so that `a ≤ 0`: the sampled variable is s·(y − μ)/σ ∈ [a, b].
    a: f64,
    b: f64,
    flip: bool,
    /// Φ(a) (0 if a < −`NEGLIGIBLE_TAIL` < 0 < b).
    p_a: f64,
    /// Φ(b) if b ≤ 0, else 1 − Φ(b) (0 if b > `NEGLIGIBLE_TAIL`).
    p_b: f64,
    /// The mass of [a, b]; 0 selects the uniform fallback.
    z: f64,
    /// 1 / (σ √(2π) Z), the pdf's normalisation (1/(hi − lo) for the uniform fallback).
    norm: f64,
}

impl TruncatedGaussian {
    /// N(`mu`, `sigma`²) on [`lo`, `hi`], `sigma` > 0, `lo` < `hi`.
    #[inline]
    pub fn new(mu: f64, sigma: f64, lo: f64, hi: f64) -> TruncatedGaussian {
        let (mut a, mut b) = ((lo - mu) / sigma, (hi - mu) / sigma);
        let flip = a > 0.0;
        if flip {
            (a, b) = (-b, -a);
        }
        let p_b = if b <= 0.0 {
            normal_cdf(b)
        } else if b > NEGLIGIBLE_TAIL {
            0.0
        } else {
            normal_cdf(-b)
        };
        let p_a = if b > 0.0 && a < -NEGLIGIBLE_TAIL {
            0.0
        } else {
            normal_cdf(a)
        };
        // The mass, from the tails already at hand (lower tails if both ends are below the mean: relative
        // accuracy far out). When it is small because [a, b] is narrow around the mean (σ ≫ hi − lo), that
        // difference cancels; erf's series near 0 does not.
        let z = if b <= 0.0 { p_b - p_a } else { 1.0 - p_a - p_b };
        let z = if z < 0.1 && a > -0.7 && b < 0.7 {
            0.5 * (erf(b * FRAC_1_SQRT_2) - erf(a * FRAC_1_SQRT_2))
        } else {
            z
        };
        // Interval mass below what a double resolves: uniform fallback (see the type's docs).
        let z = if z > 1e-300 && z.is_finite() { z } else { 0.0 };
        let norm = if z == 0.0 {
            1.0 / (hi - lo)
        } else {
            1.0 / ((std::f64::consts::TAU).sqrt() * sigma * z)
        };
        TruncatedGaussian {
            mu,
            sigma,
            lo,
            hi,
            a,
            b,
            flip,
            p_a,
            p_b,
            z,
            norm,
        }
    }

    /// The mass of N(μ, σ²) inside [lo, hi] (0 if it underflows).
    pub fn mass(&self) -> f64 {
        self.z
    }

    /// The value at CDF level `u` ∈ [0, 1].
    #[inline]
    pub fn sample(&self, u: f64) -> f64 {
        if self.z == 0.0 {
            return self.lo + u * (self.hi - self.lo);
        }
        let x = standardised_inverse_cdf(u, self.flip, self.p_a, self.z, self.p_b, self.a, self.b);
        (self.mu + self.sigma * x).clamp(self.lo, self.hi)
    }

    /// The density at `y` (0 outside [lo, hi]).
    #[inline]
    pub fn pdf(&self, y: f64) -> f64 {
        if !(self.lo..=self.hi).contains(&y) {
            return 0.0;
        }
        if self.z == 0.0 {
            return self.norm;
        }
        let x = (y - self.mu) / self.sigma;
        (-0.5 * x * x).exp() * self.norm
    }
}

/// The exponent below which [`exp_lobe_of`] returns 0: −87.3, where e^x leaves the normal f32 range
/// (e^{−87.3} ≈ 1.2e-38) and where `wide`'s vector exponential returns 0.
pub const EXP_LOBE_MIN_OF: f32 = -87.3;

/// [`exp_lobe`] over the number type [`Real`] (one f32 or eight lanes): e^x for the
/// non-positive exponents of Gaussian lobes, 0 at and below [`EXP_LOBE_MIN_OF`]. The cut is where `wide`'s f32x8
/// exponential stops (it returns 0 there), so that both number types agree lane by lane; it drops values ≤ 1.2e-38
/// (the edge of the normal f32 range, 1e-38 of a lobe's unit peak), which no pixel can show. When every lane is
/// below, no exponential is taken (for f32 the comparison is the branch [`exp_lobe`] takes: narrow lobes underflow
/// for most directions, and libm's underflow path is slow).
#[inline(always)]
pub fn exp_lobe_of<R: crate::util::real::Real>(x: R) -> R {
    let zero = R::splat(0.0);
    let under = x.le(R::splat(EXP_LOBE_MIN_OF));
    if crate::util::real::RealMask::all(under) {
        return zero;
    }
    R::select(under, zero, x.exp())
}

/// The exponent −(x/β)²/2 of a unit-height Gaussian over [`Real`], given 1/β
/// (`inv_beta`): [`gaussian_exponent`] with the division taken once by the caller (a multiplication per call;
/// differs from x/β by one rounding).
#[inline(always)]
pub fn gaussian_exponent_of<R: crate::util::real::Real>(inv_beta: R, x: R) -> R {
    let z = x * inv_beta;
    R::splat(-0.5) * z * z
}

#[cfg(test)]
mod tests;

// Over any `Real` (one f32 or eight lanes, `crate::util::real`): the pieces of the truncated Gaussian that the
// fibre models' generic code samples and evaluates with, vectorised where f32 serves and lane by lane in f64 where
// it does not (say so where it happens).

/// ½ erfc(z/√2) = Φ(−z) for z ≥ 0 over any [`Real`] (`upper_tail_f32`'s arithmetic, z in f32), 0 beyond
/// `NEGLIGIBLE_TAIL`.
#[inline(always)]
pub fn upper_tail_of<R: Real>(z: R) -> R {
    let far = z.gt(R::splat(NEGLIGIBLE_TAIL as f32));
    if far.all() {
        return R::splat(0.0);
    }
    let z = z * R::splat(FRAC_1_SQRT_2 as f32);
    let (t, p) = erfc_parts(z);
    R::select(far, R::splat(0.0), R::splat(0.5) * t * (-z * z + p).exp())
}

/// Φ⁻¹(p) over any [`Real`], in f32: Wichura 1988's `PPND7` (AS 241's seven-digit companion of [`normal_quantile`]'s
/// `PPND16`): a rational function of degree 3/3 in (p − ½)² for |p − ½| ≤ 0.425, else of degree 3/2 in
/// r = √(−ln min(p, 1 − p)) (two pieces, split at r = 5). Relative accuracy about 1e-7, the f32 result's own, for
/// every p whose nearer tail is a normal f32. That suffices where the samplers use it: their levels are always the
/// nearer tail (≤ ½), formed with relative accuracy, so f32 loses nothing that f64 would keep (tested against
/// [`normal_quantile`]). p ≤ 0 gives −∞ and p ≥ 1 gives +∞. The tail pieces (a logarithm) are computed only when
/// some lane needs them.
// The coefficients are AS 241's ten-digit ones as published, kept verbatim so they can be checked against it.
#[allow(clippy::excessive_precision)]
#[inline(always)]
pub fn normal_quantile_of<R: Real>(p: R) -> R {
    let c = R::splat;
    let q = p - c(0.5);
    let r = c(0.180_625) - q * q;
    let num = ((c(5.910_937_472e1) * r + c(1.592_911_320_2e2)) * r + c(5.043_427_193_8e1)) * r
        + c(3.387_132_717_9);
    let den =
        ((c(6.718_756_36e1) * r + c(7.875_775_766_4e1)) * r + c(1.789_516_946_9e1)) * r + c(1.0);
    let central = q.abs().le(c(0.425));
    let x = q * num / den;
    if central.all() {
        return x;
    }
    // The nearer tail's probability; below the smallest normal f32 only the infinities below are returned.
    let s = p.min(c(1.0) - p);
    let r = (-(s.max(c(f32::MIN_POSITIVE))).ln()).sqrt();
    let near = r.le(c(5.0));
    let rc = r - c(1.6);
    let mut t = (((c(1.702_382_110_3e-1) * rc + c(1.306_728_481_6)) * rc + c(2.756_815_39)) * rc
        + c(1.423_437_277_7))
        / ((c(1.202_113_297_5e-1) * rc + c(7.370_016_425e-1)) * rc + c(1.0));
    if !near.all() {
        let re = r - c(5.0);
        let far = (((c(1.733_720_399_7e-2) * re + c(4.286_829_433_7e-1)) * re + c(3.081_226_386))
            * re
            + c(6.657_905_115))
            / ((c(1.225_820_263_5e-2) * re + c(2.419_789_422_5e-1)) * re + c(1.0));
        t = R::select(near, t, far);
    }
    let lower = q.lt(c(0.0));
    let t = R::select(s.le(c(0.0)), c(f32::INFINITY), t);
    R::select(central, x, R::select(lower, -t, t))
}

/// [`TruncatedGaussianF32`] over any [`Real`], the distribution per lane: N(μ, σ²) on [lo, hi], sampled by
/// inverse CDF, with the matching pdf. The three cases of [`TruncatedGaussianF32`] (after mirroring so that
/// a ≤ 0):
///
/// - **Central** (b > 0), vectorised in f32: tails Φ(a) and 1 − Φ(b) ([`upper_tail_of`]),
///   Z = 1 − Φ(a) − (1 − Φ(b)) (≥ 0.38 for the models' ranges, so it does not cancel), pdf = e^{−x²/2}/(σ√(2π) Z);
///   the sampler inverts that CDF with the same f32 tails and Z and [`normal_quantile_of`], so it draws exactly the
///   density `pdf` returns up to f32 rounding (tested against the f64 [`TruncatedGaussian`]).
/// - **Tail** (b ≤ 0: the interval on one side of the mean, a lobe whose shift puts it outside the view's range),
///   pdf vectorised in f32 as [`TruncatedGaussianF32`]'s: Z = ½ e^{−b²/2} [T(|b|/√2) − T(|a|/√2) e^{−(a² − b²)/2}]
///   and density e^{−(x² − b²)/2}, with each (u² − v²)/2 = ½(u − v)(u + v) formed from distances between f32
///   angles (|y − n| for x − b, n the end nearer the mean), which neither cancel nor overflow however far out the
///   interval is. Sampling there needs the tails' levels themselves (e^{−b²/2} underflows f32 beyond |b| ≈ 13), so
///   those lanes draw from the f64 [`TruncatedGaussian`] one at a time (`R::from_fn`); rare.
/// - **Uniform**: where the interval's mass underflows a double, both read the f64 type's uniform fallback.
///
/// Precision: the standardised ends and points are formed in f32 (the f64 type forms them in f64). Differences
/// of angles are exact where they cancel (Sterbenz), so a standardised value carries ≈ 2e-7 relative error and
/// an exponent −e ≈ 4e-7·e, < 1e-5 where the density is within e^{−20} of its peak: below what the models' own
/// angles carry (an arctangent's 6e-7 rad is 6e-7/σ in x). The ends are f32 angles (≤ 3e-8 rad from the f64 ones),
/// which moves where the interval is cut, not the agreement of sampler and pdf. Z = 1 − p_a − p_b is rounded once
/// more in f32 (6e-8 relative), so the sampler's two halves meet at the median within that.
#[derive(Clone, Copy)]
pub struct TruncatedGaussianOf<R: Real> {
    mu: R,
    sigma: R,
    lo: R,
    hi: R,
    /// Standardised and, where `flip`, mirrored ends: the variable s·(y − μ)/σ ∈ [a, b] with a ≤ 0. The central
    /// case is b > 0.
    a: R,
    b: R,
    flip: R::Mask,
    /// 1/σ.
    inv_sigma: R,
    /// Φ(a), 1 − Φ(b), Z and 1/Z (central lanes; finite and unused elsewhere).
    p_a: R,
    p_b: R,
    z: R,
    inv_z: R,
    /// Tail lanes: the end n nearer the mean and |n − μ| = −bσ, P(t_b), 1/(scaled mass) and the uniform fallback
    /// (unused elsewhere).
    near: R,
    near_dist: R,
    tail_p_b: R,
    tail_inv_scaled: R,
    uniform: R::Mask,
}

impl<R: Real> TruncatedGaussianOf<R> {
    /// N(`mu`, `sigma`²) on [`lo`, `hi`] per lane; `inv_sigma` = 1/`sigma` (callers keep both: no division here).
    #[inline(always)]
    pub fn new(mu: f32, sigma: f32, inv_sigma: f32, lo: R, hi: R) -> TruncatedGaussianOf<R> {
        let (m, is) = (R::splat(mu), R::splat(inv_sigma));
        let (a0, b0) = ((lo - m) * is, (hi - m) * is);
        let flip = a0.gt(R::splat(0.0));
        let (a, b) = (R::select(flip, -b0, a0), R::select(flip, -a0, b0));
        let zero = R::splat(0.0);
        let p_a = upper_tail_of((-a).max(zero));
        let p_b = upper_tail_of(b.max(zero));
        let z = R::splat(1.0) - p_a - p_b;
        let central = b.gt(zero);
        let (near, far) = (R::select(flip, lo, hi), R::select(flip, hi, lo));
        let near_dist = (near - m).abs();
        let (mut tail_p_b, mut tail_inv_scaled, mut uniform) = (zero, zero, zero.lt(zero));
        if !central.all() {
            // The tail case, as `TruncatedGaussianF32::new`: T and P of both ends' standardised distances
            // |b| = |n − μ|/σ and |a| = |f − μ|/σ, and (a² − b²)/2 = ½ · (hi − lo)/σ · (|f − μ| + |n − μ|)/σ.
            let far_dist = (far - m).abs();
            let h = R::splat(FRAC_1_SQRT_2 as f32);
            let (tb, pb) = erfc_parts(near_dist * is * h);
            let (ta, pa) = erfc_parts(far_dist * is * h);
            let d = R::splat(0.5) * ((hi - lo) * is) * ((far_dist + near_dist) * is);
            // e^{−40} is below f32's resolution: the far end's tail is then negligible.
            let ratio = R::select(d.gt(R::splat(40.0)), zero, ta / tb * (pa - pb - d).exp());
            let scaled = R::splat(0.5) * tb * (R::splat(1.0) - ratio);
            // Mass = scaled · e^{−b²/2 + P(t_b)}: below 1e-300 (ln = −690.8) the f64 type is uniform.
            let nb = near_dist * is;
            let log_mass = R::splat(-0.5) * nb * nb + pb + scaled.ln();
            uniform = !central & nb.gt(R::splat(36.0)) & log_mass.le(R::splat(-690.775_5));
            (tail_p_b, tail_inv_scaled) = (pb, R::splat(1.0) / scaled);
        }
        TruncatedGaussianOf {
            mu: m,
            sigma: R::splat(sigma),
            lo,
            hi,
            a,
            b,
            flip,
            inv_sigma: is,
            p_a,
            p_b,
            z,
            inv_z: R::splat(1.0) / z,
            near,
            near_dist,
            tail_p_b,
            tail_inv_scaled,
            uniform,
        }
    }

    /// Per lane: `x`'s distribution where `m` is set, else `y`'s.
    #[inline(always)]
    pub fn pick(m: R::Mask, x: &Self, y: &Self) -> Self {
        let s = |a: R, b: R| R::select(m, a, b);
        TruncatedGaussianOf {
            mu: s(x.mu, y.mu),
            sigma: s(x.sigma, y.sigma),
            lo: s(x.lo, y.lo),
            hi: s(x.hi, y.hi),
            a: s(x.a, y.a),
            b: s(x.b, y.b),
            flip: (m & x.flip) | (!m & y.flip),
            inv_sigma: s(x.inv_sigma, y.inv_sigma),
            p_a: s(x.p_a, y.p_a),
            p_b: s(x.p_b, y.p_b),
            z: s(x.z, y.z),
            inv_z: s(x.inv_z, y.inv_z),
            near: s(x.near, y.near),
            near_dist: s(x.near_dist, y.near_dist),
            tail_p_b: s(x.tail_p_b, y.tail_p_b),
            tail_inv_scaled: s(x.tail_inv_scaled, y.tail_inv_scaled),
            uniform: (m & x.uniform) | (!m & y.uniform),
        }
    }

    /// Lane `k` as the f32-normalised scalar type, in f64 (sampling the tail and uniform cases).
    #[inline(never)]
    fn lane_f64(&self, k: usize) -> TruncatedGaussianF32 {
        let sigma = self.sigma.lane(k) as f64;
        TruncatedGaussianF32::new(
            self.mu.lane(k) as f64,
            sigma,
            1.0 / sigma,
            self.lo.lane(k) as f64,
            self.hi.lane(k) as f64,
        )
    }

    /// The density at `y` (0 outside [lo, hi]), given `g` = e^{−x²/2}/(σ√(2π)) at its standardised point x (a
    /// caller that has it already, Marschner's M, shares one exponential): g/Z in central lanes; tail lanes
    /// take their own exponential, of −(x² − b²)/2 = −½ · |y − n|/σ · (|y − μ| + |n − μ|)/σ (g would underflow).
    #[inline(always)]
    pub fn pdf_given(&self, y: R, g: R) -> R {
        let central = self.b.gt(R::splat(0.0));
        let mut p = g * self.inv_z;
        if !central.all() {
            let is = self.inv_sigma;
            let e = R::splat(0.5)
                * ((y - self.near).abs() * is)
                * (((y - self.mu).abs() + self.near_dist) * is);
            let norm = R::splat(INV_SQRT_TAU) * is;
            let tail = norm * (-e - self.tail_p_b).exp() * self.tail_inv_scaled;
            let tail = if self.uniform.any() {
                R::select(self.uniform, R::splat(1.0) / (self.hi - self.lo), tail)
            } else {
                tail
            };
            p = R::select(central, p, tail);
        }
        let inside = self.lo.le(y) & y.le(self.hi);
        R::select(inside, p, R::splat(0.0))
    }

    /// The value at CDF level `u` ∈ [0, 1]: in central lanes Φ⁻¹ of the lower-tail level p_a + uZ below the
    /// median and −Φ⁻¹ of the upper-tail level p_b + (1 − u)Z above it (mirrored lanes run the other way, with
    /// u and 1 − u swapped rather than 1 − u formed twice); the other lanes draw from the f64
    /// [`TruncatedGaussian`], as [`TruncatedGaussianF32::sample`] does.
    #[inline(always)]
    pub fn sample(&self, u: R) -> R {
        let one = R::splat(1.0);
        let v = one - u;
        let (lower_u, upper_u) = (R::select(self.flip, v, u), R::select(self.flip, u, v));
        let t = self.p_a + lower_u * self.z;
        let lower = t.le(R::splat(0.5));
        let level = R::select(lower, t, self.p_b + upper_u * self.z);
        let q = normal_quantile_of(level);
        // Clamped to [a, b] (an infinite quantile at level 0 lands on the end).
        let x = R::select(lower, q, -q).max(self.a).min(self.b);
        let x = R::select(self.flip, -x, x);
        let mut y = (self.mu + self.sigma * x).max(self.lo).min(self.hi);
        let central = self.b.gt(R::splat(0.0));
        if !central.all() {
            let other = R::from_fn(|k| {
                if self.b.lane(k) > 0.0 {
                    0.0
                } else {
                    self.lane_f64(k).sample(u.lane(k) as f64) as f32
                }
            });
            y = R::select(central, y, other);
        }
        y
    }
}

#[cfg(test)]
mod tests_of;
