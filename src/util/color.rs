//! Colour: RGB to luminance.

use glam::Vec3;

/// The Rec. 709 (sRGB primaries, D65) luminance weights of linear R, G, B; they sum to 1.
pub const REC709_LUMINANCE: Vec3 = Vec3::new(0.2126, 0.7152, 0.0722);

/// Luminance Y of a linear Rec. 709 RGB triple: turns RGB lobe colours, light powers and texels into the scalar
/// weights of sampling probabilities.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(REC709_LUMINANCE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_is_one_and_primaries_are_their_weights() {
        assert!((luminance(Vec3::ONE) - 1.0).abs() < 1e-6);
        assert_eq!(luminance(Vec3::X), 0.2126);
        assert_eq!(luminance(Vec3::Y), 0.7152);
        assert_eq!(luminance(Vec3::Z), 0.0722);
        assert_eq!(luminance(Vec3::ZERO), 0.0);
        // Linear: grey g has luminance g.
        assert!((luminance(Vec3::splat(0.25)) - 0.25).abs() < 1e-7);
    }
}
