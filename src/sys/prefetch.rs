//! A cache prefetch hint as a safe function.

/// Asks the CPU to bring the cache lines holding `value` into every cache level (x86-64 `PREFETCHT0`;
/// nothing elsewhere). A hint only: it changes no result and cannot fault.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: PREFETCHT0 never faults and reads nothing architecturally; the address comes from a live reference.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let start = (value as *const T).cast::<i8>();
        let size = std::mem::size_of::<T>();
        let mut offset = 0;
        while offset < size {
            _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(offset));
            offset += 64;
        }
        // The last byte: a value not aligned to the line size may reach into one more line.
        if size > 0 {
            _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(size - 1));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}
