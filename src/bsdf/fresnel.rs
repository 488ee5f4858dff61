//! Unpolarised Fresnel reflectance of a dielectric interface, used by [`super::Balance::Fresnel`] (thesis §8.2:
//! balancing specular and diffuse on a Fresnel-based coefficient).

/// F_r for light arriving at cosine `cos_i` (clamped to [0, 1]) on a dielectric of relative index `eta` (> 0):
/// the mean of the s- and p-polarised reflectances (Fresnel equations; e.g. pbrt-v4 §9.3.2 `FrDielectric`).
/// Returns 1 under total internal reflection (only possible for `eta` < 1).
#[inline]
pub fn dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    // Snell: sin θt = sin θi / η.
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let f = 0.5 * (r_parl * r_parl + r_perp * r_perp);
    debug_assert!(f.is_finite(), "fresnel({cos_i}, {eta}) = {f}");
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
