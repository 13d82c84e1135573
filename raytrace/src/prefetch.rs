//! Cache hints for gathers whose addresses are known before their loads: a hit's SH
//! coefficients in the Gaussian tile walk (`gaussian::lanes`), the triangle entries and vertex
//! parameters of hits further down a distillation pass (`distill::composite`).

/// Hint the cache to fetch every 64-byte line `xs` touches: its first byte, every 64th, and
/// its last (nothing for an empty slice, or off x86-64).
#[inline(always)]
pub fn lines<T>(xs: &[T]) {
    let len = std::mem::size_of_val(xs);
    if len == 0 {
        return;
    }
    let start = xs.as_ptr().cast::<u8>();
    for at in (0..len).step_by(64).chain(std::iter::once(len - 1)) {
        hint(start.wrapping_add(at));
    }
}

/// Hint the cache to fetch the line `xs[i]` starts on (nothing when `i` is out of range).
#[inline(always)]
pub fn at<T>(xs: &[T], i: usize) {
    if let Some(x) = xs.get(i) {
        hint((x as *const T).cast::<u8>());
    }
}

#[inline(always)]
fn hint(p: *const u8) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint without architectural effect: it reads nothing the program
    // sees and cannot fault; callers pass addresses inside a live slice.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
