//! Runs Embree's traversal with flush-to-zero and denormals-are-zero set, as
//! Embree advises for speed, without exposing Rust code to that mode.
//!
//! Rust assumes the default floating-point environment everywhere: setting
//! FTZ/DAZ for a whole thread (`_mm_setcsr`) is undefined behaviour for the
//! Rust code that runs afterwards. So the mode is set, the Embree function
//! called, and MXCSR restored within one `asm!` block; Rust never observes
//! the changed mode.

/// Calls the C function at `f` with the four pointer-sized arguments `args`
/// (System V order, hence unix only), FTZ and DAZ set for the duration of
/// the call only.
/// Functions taking three arguments ignore the fourth.
///
/// # Safety
/// `f` must be an `extern "C"` function whose parameters are four (or
/// fewer) pointer-sized integers or pointers, and calling it with `args`
/// must be sound.
#[cfg(all(target_arch = "x86_64", unix))]
#[inline(always)]
pub(super) unsafe fn call_ftz(f: *const (), args: [usize; 4]) {
    /// MXCSR bit 15 (flush to zero) and bit 6 (denormals are zero).
    const FTZ_DAZ: u32 = 0x8040;
    // [saved MXCSR, MXCSR with FTZ|DAZ]
    let mut csr = [0u32; 2];
    // SAFETY: the caller vouches for `f` and its arguments. Every operand
    // sits in an explicit register, so the scratch eax aliases none. The
    // block saves MXCSR through r12 (callee-saved, so it survives the call), sets
    // FTZ|DAZ, calls `f` with the C ABI (`clobber_abi("C")` tells the
    // compiler every caller-saved register is lost; the stack is aligned
    // for a call on entry to a block without `nostack`), then restores the
    // saved MXCSR before control returns to Rust.
    unsafe {
        core::arch::asm!(
            "stmxcsr [r12]",
            "mov eax, [r12]",
            "or eax, {bits}",
            "mov [r12 + 4], eax",
            "ldmxcsr [r12 + 4]",
            "call r11",
            "ldmxcsr [r12]",
            bits = const FTZ_DAZ,
            in("r11") f,
            in("r12") csr.as_mut_ptr(),
            in("rdi") args[0],
            in("rsi") args[1],
            in("rdx") args[2],
            in("rcx") args[3],
            clobber_abi("C"),
        );
    }
}

/// Elsewhere (other architectures, or x86_64 with the Windows calling
/// convention, whose argument registers differ from the ones named above)
/// the call is made in the default floating-point mode.
#[cfg(not(all(target_arch = "x86_64", unix)))]
#[inline(always)]
pub(super) unsafe fn call_ftz(f: *const (), args: [usize; 4]) {
    // SAFETY: the caller vouches for `f` and its arguments.
    unsafe {
        let f: unsafe extern "C" fn(usize, usize, usize, usize) =
            core::mem::transmute::<*const (), _>(f);
        f(args[0], args[1], args[2], args[3]);
    }
}
