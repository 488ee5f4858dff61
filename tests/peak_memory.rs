//! The peak-memory reset the studies rely on (`cuticle::measure`), alone in its own test binary: another test
//! allocating in a parallel thread of the same process between the reset and the read would make it fail.

use cuticle::measure::{peak_rss_bytes, reset_peak_rss};

#[test]
#[cfg_attr(
    not(target_os = "linux"),
    ignore = "the peak is reset through /proc/self/clear_refs: Linux only"
)]
fn peak_memory_can_be_reset() {
    // 64 MB touched then freed: the peak covers it; after a reset it no longer does.
    let big = vec![1u8; 64 << 20];
    assert!(big.iter().map(|&b| u64::from(b)).sum::<u64>() > 0);
    let with = peak_rss_bytes().unwrap();
    drop(big);
    assert!(reset_peak_rss());
    let after = peak_rss_bytes().unwrap();
    assert!(after + (32 << 20) < with, "peak {with} -> {after}");
}
