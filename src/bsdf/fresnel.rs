//! Unpolarised Fresnel reflectance of a dielectric interface, used by [`super::Balance::Fresnel`] (thesis §8.2:
//! balancing specular and diffuse on a Fresnel-based coefficient).

use crate::util::real::{Real, RealMask};

/// F_r for light arriving at cosine `cos_i` (clamped to [0, 1]) on a dielectric of relative index `eta` (> 0):
/// the mean of the s- and p-polarised reflectances (Fresnel equations; e.g. pbrt-v4 §9.3.2 `FrDielectric`).
/// Returns 1 under total internal reflection (only possible for `eta` < 1). Generic over the number type
/// ([`Real`]): one cosine per lane.
#[inline]
pub fn dielectric<R: Real>(cos_i: R, eta: f32) -> R {
    let one = R::splat(1.0);
    let cos_i = cos_i.clamp_to(0.0, 1.0);
    let eta = R::splat(eta);
    // Snell: sin θt = sin θi / η.
    let sin2_t = (one - cos_i * cos_i) / (eta * eta);
    let total = one.le(sin2_t);
    if total.all() {
        return one;
    }
    // Lanes past the critical angle take 1 below; the max keeps their square root real meanwhile.
    let cos_t = (one - sin2_t).max(R::splat(0.0)).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let f = R::splat(0.5) * (r_parl * r_parl + r_perp * r_perp);
    let f = R::select(total, one, f);
    debug_assert!(
        (0..R::LANES).all(|k| f.lane(k).is_finite()),
        "fresnel({cos_i:?}, {eta:?}) = {f:?}",
        cos_i = (0..R::LANES).map(|k| cos_i.lane(k)).collect::<Vec<_>>(),
        eta = eta.lane(0),
        f = (0..R::LANES).map(|k| f.lane(k)).collect::<Vec<_>>(),
    );
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        // Normal incidence: ((η − 1)/(η + 1))², 0.04 for η = 1.5; grazing: 1.
        assert!((dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert!((dielectric(0.0, 1.55) - 1.0).abs() < 1e-6);
        // 45° on glass (η = 1.5): Rs = 0.0920, Rp = 0.00846, mean 0.0502.
        let f45 = dielectric(std::f32::consts::FRAC_1_SQRT_2, 1.5);
        assert!((f45 - 0.0502).abs() < 2e-4, "{f45}");
        // Total internal reflection from inside (η < 1) past the critical angle.
        assert_eq!(dielectric(0.1, 1.0 / 1.5), 1.0);
    }
}
