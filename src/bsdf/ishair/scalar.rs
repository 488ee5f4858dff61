//! ISHair's draw behind `Fibre::sample_view`, and its scalar `Bsdf` (the generic code at `f32`).

use super::*;

impl IsHair {
    /// The direction [`Fibre::sample_view`] draws, with the angles of its pair and the lobe chosen (its index in
    /// [`Lobe::ALL`], −1 for [`Sampling::Uniform`]).
    #[inline(always)]
    pub(super) fn draw<R: Real>(&self, v: &IsHairView<R>, u: [R; 3]) -> ([R; 3], Pair<R>, R) {
        if self.params.sampling == Sampling::Uniform {
            // The sphere, the baseline of thesis §7 (`uniform_sphere`, lane by lane: the one implementation).
            let wi = uniform_sphere_of(u[0], u[1]);
            return (wi, Pair::of_directions(v, wi), R::splat(-1.0));
        }
        // Diffuse or specular by u0 against p_s.
        branch!(
            u[0].lt(v.p_s),
            self.sample_specular_lanes(v, u),
            self.sample_diffuse_lanes(v, u),
            |m, s: ([R; 3], Pair<R>, R), d: ([R; 3], Pair<R>, R)| {
                (
                    blend(m, s.0, d.0),
                    Pair::blend(m, s.1, d.1),
                    R::select(m, s.2, d.2),
                )
            }
        )
    }
}

/// The scalar form: the generic code at `R = f32` ([`At`]; ISHair does not read h).
impl Bsdf for IsHair {
    #[inline]
    fn eval_lobes(&self, wo: Vec3, wi: Vec3) -> LobeValues {
        At {
            model: self,
            h: 0.0,
        }
        .eval_lobes(wo, wi)
    }

    /// The lobes summed where they are computed ([`IsHair::f_at`]): the generic code at f32, as [`At`] runs it, but
    /// inlined here (`At::eval_lobes` is kept out of line, and its lobes then pass through memory).
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let view = self.view(0.0f32, wo.to_array());
        self.f_at(&view, &Pair::of_directions(&view, wi.to_array()))
    }

    /// [`Fibre::sample_view`] at f32 (what [`At`] runs), with f summed as in [`IsHair::eval`].
    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let view = self.view(0.0f32, wo.to_array());
        let (wi, a, lobe) = self.draw(&view, u);
        make_sample(
            Vec3::from_array(wi),
            self.f_at(&view, &a),
            self.pdf_at(&view, &a),
            a.cos_i,
            (lobe >= 0.0).then(|| Lobe::ALL[lobe as usize]),
        )
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        At {
            model: self,
            h: 0.0,
        }
        .pdf(wo, wi)
    }
}
