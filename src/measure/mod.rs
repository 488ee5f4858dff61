//! Measuring tools shared by the benchmarks ([`crate::bench`]) and the studies ([`crate::study`]): repeated
//! timings, the process's peak memory, and image error against a reference ([`metrics`]). Neither of those two
//! layers imports the other; both import this.

pub mod albedo;
pub mod metrics;
pub mod pixels;

/// Median and spread of repeated timings, in seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Median.
    pub median: f64,
    /// Fastest.
    pub min: f64,
    /// Slowest.
    pub max: f64,
}

impl Timing {
    /// Median, min and max of `seconds` (NaN if empty).
    pub fn from_samples(mut seconds: Vec<f64>) -> Self {
        seconds.sort_by(f64::total_cmp);
        let n = seconds.len();
        if n == 0 {
            return Timing {
                median: f64::NAN,
                min: f64::NAN,
                max: f64::NAN,
            };
        }
        let median = if n % 2 == 1 {
            seconds[n / 2]
        } else {
            0.5 * (seconds[n / 2 - 1] + seconds[n / 2])
        };
        Timing {
            median,
            min: seconds[0],
            max: seconds[n - 1],
        }
    }
}

/// Peak resident set size of this process (`VmHWM` in `/proc/self/status`), in bytes.
pub fn peak_rss_bytes() -> Option<u64> {
    status_kb("VmHWM:").map(|kb| kb * 1024)
}

/// A `kB` field of `/proc/self/status` (`field` with its colon, e.g. `"VmRSS:"`); `None` where it cannot be read.
pub fn status_kb(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Resets this process's peak resident set size to its current size (writes `5` to `/proc/self/clear_refs`,
/// Linux ≥ 4.0), so that [`peak_rss_bytes`] afterwards reports the peak of what ran since. Returns whether it
/// worked (never on other platforms; then the peak keeps covering the whole process life).
pub fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", b"5").is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_and_spread() {
        let t = Timing::from_samples(vec![3.0, 1.0, 2.0]);
        assert_eq!((t.median, t.min, t.max), (2.0, 1.0, 3.0));
        assert_eq!(Timing::from_samples(vec![1.0, 2.0]).median, 1.5);
    }

    #[test]
    fn reads_peak_memory() {
        if cfg!(target_os = "linux") {
            assert!(peak_rss_bytes().is_some_and(|b| b > 0));
        }
    }
}
