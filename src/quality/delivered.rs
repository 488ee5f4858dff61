//! What an auto render delivered: the error it estimates for the frame once rendered, from the noise adaptive
//! sampling's stop read in the frame itself and the bias of the bounces the pilots left out, √(noise² + bias²), and
//! why it may miss the target (pixels held at the schedule's cap, a fixed spp, a cancelled render).
//!
//! The noise is the stop's own reading after the last round ([`NoiseEstimate`]): the larger of two estimates (the
//! pixels' variances over their counts and the sampler's gain, and the pixels' halves), over the frame's own means,
//! times √darkening to be over the converged image's as the target is ([`PilotPlan::darkening`]); the smaller of the
//! two gives the low end of its range. The bias is the pilots' estimate of the bounces left out
//! ([`PilotPlan::bias_left`]) and of the approximations kept ([`PilotPlan::approximations`]: ribbons, deep
//! opacity maps), added in quadrature. The light threshold's bias is not measured yet, nor is that of an
//! approximation the user fixed.

use crate::render::adaptive::NoiseEstimate;

use super::denoised::Rounds;
use super::pilot::PilotPlan;

/// An auto render's estimate of its own error, relative RMSE against the converged image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Delivered {
    /// √(noise² + bias²).
    pub error: f64,
    /// The noise: read from the frame under adaptive sampling, else the pilots' prediction at the fixed spp.
    pub noise: f64,
    /// The two estimates of the noise, smaller first (both the prediction when there was no adaptive stop).
    pub noise_range: (f64, f64),
    /// Whether the noise was read from the frame (adaptive sampling) rather than predicted by the pilots.
    pub read_from_frame: bool,
    /// The bias of the bounces left out and the approximations kept together, if the pilots measured the bounces'.
    pub bias: Option<f64>,
    /// How many approximations' biases `bias` holds beside the bounces'.
    pub approximations: usize,
    /// The target.
    pub target: f32,
    /// Fraction of pixels held at the schedule's cap, and the cap (adaptive sampling only).
    pub capped: Option<(f64, u32)>,
    /// Whether `noise` is the denoised frame's error (the filter's smoothing with its leftover noise) as its rounds
    /// measured it ([`super::denoised`]).
    pub denoised: bool,
}

/// The estimate for a frame planned as `pilot` for `target`, whose render's stop read `noise` (`None` without
/// adaptive sampling or when the render was cancelled).
pub fn delivered(pilot: &PilotPlan, target: f32, noise: Option<&NoiseEstimate>) -> Delivered {
    let scale = pilot.darkening.sqrt();
    let (n, range, read, capped) = match noise {
        Some(e) => {
            let (lo, hi) = e.range();
            let capped = e.capped as f64 / e.pixels.max(1) as f64;
            (
                e.rel_rmse() * scale,
                (lo * scale, hi * scale),
                true,
                Some((capped, e.max)),
            )
        }
        None => {
            let p = pilot.predicted_noise;
            (p, (p, p), false, None)
        }
    };
    let approximated = super::pilot::approximations::bias2_of(&pilot.approximations);
    let bias = pilot.bias_left.map(|b| (b * b + approximated).sqrt());
    let b = bias.unwrap_or(approximated.sqrt());
    Delivered {
        error: (n * n + b * b).sqrt(),
        noise: n,
        noise_range: range,
        read_from_frame: read,
        bias,
        approximations: pilot.approximations.len(),
        target,
        capped,
        denoised: false,
    }
}

/// The estimate for a frame planned as `pilot` for `target` and rendered in denoised rounds ([`super::denoised`]):
/// the last round's predicted denoised error (point and upper bound) in place of the noise.
pub fn delivered_denoised(pilot: &PilotPlan, target: f32, rounds: &Rounds) -> Delivered {
    let mut d = delivered(pilot, target, None);
    let (point, upper) = rounds
        .last()
        .map_or((d.noise, d.noise), |r| (r.predicted, r.predicted_upper));
    let b2 = d.error * d.error - d.noise * d.noise;
    d.noise = upper;
    d.noise_range = (point, upper);
    d.error = (upper * upper + b2.max(0.0)).sqrt();
    d.read_from_frame = true;
    d.capped = Some((if rounds.capped { 1.0 } else { 0.0 }, rounds.max));
    d.denoised = true;
    d
}

impl Delivered {
    /// One line (at most 120 characters) for the end of an auto render.
    pub fn line(&self) -> String {
        let noise = if self.denoised {
            let (lo, hi) = self.noise_range;
            format!("denoised {lo:.4}–{hi:.4} from the frame's halves")
        } else if self.read_from_frame {
            let (lo, hi) = self.noise_range;
            format!("noise {lo:.4}–{hi:.4} from the frame")
        } else {
            format!("noise {:.4} predicted", self.noise)
        };
        let bias = match (self.bias, self.approximations) {
            (Some(b), 0) => format!("bias {b:.4} of bounces left out"),
            (Some(b), n) => format!("bias {b:.4} of bounces + {n} approx."),
            (None, 0) => "bias not measured".to_owned(),
            // No bounce left out to measure (dual scattering ends paths at the first vertex): the approximations'.
            (None, n) => format!(
                "bias {:.4} of {n} approx.",
                (self.error * self.error - self.noise * self.noise)
                    .max(0.0)
                    .sqrt()
            ),
        };
        format!(
            "auto: estimated error {:.4} for target {} ({noise}, {bias})",
            self.error, self.target
        )
    }

    /// Why the estimate is over the target, if it is: pixels held at the cap, or the fixed spp.
    pub fn shortfall(&self) -> Option<String> {
        if self.error <= f64::from(self.target) {
            return None;
        }
        let why = match self.capped {
            Some((_, max)) if self.denoised => {
                format!("the denoised rounds stopped at the cap of {max} spp (quality.max_spp)")
            }
            Some((fraction, max)) if fraction > 0.0 => format!(
                "{:.0} % of the pixels stopped at the cap of {max} spp (quality.max_spp)",
                100.0 * fraction
            ),
            Some(_) => "adaptive sampling ran out of rounds".to_owned(),
            None => "the samples per pixel were fixed".to_owned(),
        };
        Some(format!(
            "auto's estimated error {:.4} is over the target {}: {why}",
            self.error, self.target
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn said(bias: Option<f64>, approximations: usize) -> Delivered {
        Delivered {
            error: 0.25,
            noise: 0.2,
            noise_range: (0.19, 0.2),
            read_from_frame: true,
            bias,
            approximations,
            target: 0.3,
            capped: None,
            denoised: false,
        }
    }

    /// The line names the bias it holds: the bounces' with the approximations', the approximations' alone (dual
    /// scattering leaves no bounce out to measure: √(error² − noise²)), or none measured.
    #[test]
    fn the_line_names_the_bias_it_holds() {
        let line = said(Some(0.15), 1).line();
        assert!(
            line.contains("bias 0.1500 of bounces + 1 approx."),
            "{line}"
        );
        let line = said(None, 2).line();
        assert!(line.contains("bias 0.1500 of 2 approx."), "{line}");
        let line = said(None, 0).line();
        assert!(line.contains("bias not measured"), "{line}");
        for d in [said(Some(0.15), 3), said(None, 3)] {
            assert!(d.line().chars().count() <= 120, "{}", d.line());
        }
    }
}
