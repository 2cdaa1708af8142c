//! Bilevel Floyd–Steinberg at full strength, split into two passes per row so that the serial
//! part is as short as the method allows.
//!
//! Why: each pixel depends on the error carried from the one before it, so a row is a chain
//! of dependent steps. [`super::fixed`] already keeps that chain in integers, but it also
//! works out the three shares sent to the row below, which is more arithmetic than the chain
//! itself. Here the **chain pass** does only the chain and records, for every pixel, `X = 7e`
//! (seven times its error, exactly the product the chain needs anyway); the **spread pass**
//! recovers `e = X / 7` exactly (a multiplication by the inverse of 7 modulo 2³²) and builds
//! the next row's error from the three shares. The spread pass has no chain, so it vectorises
//! (eight lanes where the CPU has AVX2, chosen at run time).
//!
//! Measured on 24 MP in memory (one core): 64 ms for the one-pass fixed-point loop, 45 ms
//! here (about 35 ms chain, 10 ms spread). Running the spread pass on the second core a few
//! hundred pixels behind the chain was tried and gained nothing: the two cores then trade
//! every cache line of both rows, and the chain pass slowed by as much as it saved. So one
//! thread does both, in serpentine and in raster order; it is also faster than the two-thread
//! raster wavefront of [`super::fixed`] (54 ms).
//!
//! The numbers are those of [`super::fixed::FixedKernel`] for the Floyd–Steinberg weights, so
//! the bytes are the same: ahead `⌊7e/16⌋`, below-behind `⌊3e/16⌋`, below `⌊5e/16⌋`, and
//! below-ahead takes the remainder, so the four shares sum to `e` exactly.

use super::fixed::ONE;
use super::Code;
use crate::method::PlaneOut;
use crate::raster::pack_row;

/// The mid-grey threshold in fixed point.
const HALF: i32 = ONE / 2;
/// Seven times a whole pixel of light: what `X` loses when a pixel is printed white.
const SEVEN_ONE: i32 = 7 * ONE;
/// The inverse of 7 modulo 2³²: `X · INV7 = X / 7` for every multiple of 7 in `i32`.
const INV7: i32 = 0xB6DB_6DB7_u32 as i32;

/// One step of the chain: `base` is the pixel's reflectance plus the error from the row above,
/// `carry` the error from the pixel before. Returns `X = 7e` and the level (1 for white).
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn step(base: i32, carry: i32) -> (i32, u8) {
    portable_step(base, carry)
}

/// [`step`] in plain Rust (the reference the x86-64 form is tested against).
#[cfg(any(test, not(target_arch = "x86_64")))]
#[inline(always)]
fn portable_step(base: i32, carry: i32) -> (i32, u8) {
    let v = base + carry;
    let on = v >= HALF;
    (7 * v - if on { SEVEN_ONE } else { 0 }, on as u8)
}

/// [`step`] on x86-64, with the dependency from `carry` to the result held to four
/// single-cycle instructions (lea, sub, sub, sar in the caller). Written out because the
/// compiler reassociates the portable form into a longer chain (a select on the critical
/// path), which made the whole loop a third slower.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn step(base: i32, carry: i32) -> (i32, u8) {
    // Off the chain: 7·base and the threshold that `carry` must reach.
    let b7 = base.wrapping_mul(7) as u32 as u64;
    let thr = HALF - base;
    let x: u32;
    let on: u32;
    // SAFETY: register-only arithmetic; no memory, stack or flags are relied on afterwards.
    unsafe {
        std::arch::asm!(
            "lea {x:e}, [{b7} + {c}*8]",
            "xor {k:e}, {k:e}",
            "xor {on:e}, {on:e}",
            "sub {x:e}, {c:e}",
            "cmp {c:e}, {thr:e}",
            "cmovge {k:e}, {seven:e}",
            "setge {on:l}",
            "sub {x:e}, {k:e}",
            b7 = in(reg) b7,
            c = in(reg) carry as u32 as u64,
            thr = in(reg) thr,
            seven = in(reg) SEVEN_ONE,
            x = out(reg) x,
            k = out(reg) _,
            on = out(reg) on,
            options(pure, nomem, nostack),
        );
    }
    (x as i32, on as u8)
}

/// The three shares one pixel's error `e` sends below, in scan direction: behind, under,
/// ahead (the last takes the remainder, `x7 >> 4` being the share sent along the row).
#[inline(always)]
fn shares(e: i32) -> [i32; 3] {
    let ahead = (e * 7) >> 4;
    let behind = (e * 3) >> 4;
    let under = (e * 5) >> 4;
    [behind, under, e - ahead - behind - under]
}

/// Halftones one plane: for every row the chain pass, then the spread pass that makes the
/// next row's error.
pub(super) fn plane<S: Code>(
    tone: &[i32],
    codes: &[S],
    w: usize,
    out: &mut PlaneOut<'_>,
    serpentine: bool,
) {
    let h = out.height;
    let (bits, stride) = (out.bits, out.stride);
    // Error from the row above, for the row being chained.
    let mut err = vec![0i32; w];
    let mut x7 = vec![0i32; w];
    // The errors of the row just chained, with a zero either side.
    let mut e = vec![0i32; w + 2];
    let mut levels = vec![0u8; w];
    for y in 0..h {
        let fwd = !serpentine || y % 2 == 0;
        let row = &codes[y * w..(y + 1) * w];
        if fwd {
            chain::<S, true>(tone, row, &err, &mut x7, &mut levels);
        } else {
            chain::<S, false>(tone, row, &err, &mut x7, &mut levels);
        }
        pack_row(&levels, bits, &mut out.data[y * stride..(y + 1) * stride]);
        if y + 1 < h {
            spread(&x7, &mut e, &mut err, fwd);
        }
    }
}

/// The chain pass over one row, in scan order: `X = 7e` and the level of every pixel.
#[inline(always)]
pub(super) fn chain<S: Code, const FWD: bool>(
    tone: &[i32],
    codes: &[S],
    err: &[i32],
    x7: &mut [i32],
    levels: &mut [u8],
) {
    let n = codes.len();
    // Slices of one length and a table as long as the codes can reach: no bounds checks.
    let tone = &tone[..S::COUNT];
    let (err, x7, levels) = (&err[..n], &mut x7[..n], &mut levels[..n]);
    let mut carry = 0;
    for k in 0..n {
        let x = if FWD { k } else { n - 1 - k };
        let (v7, on) = step(tone[codes[x].into()] + err[x], carry);
        x7[x] = v7;
        levels[x] = on;
        carry = v7 >> 4;
    }
}

/// The spread pass: the next row's error from this row's `X`, for a row scanned forward or
/// not. `e` is scratch of the row's width + 2.
pub(super) fn spread(x7: &[i32], e: &mut [i32], next: &mut [i32], fwd: bool) {
    #[cfg(target_arch = "x86_64")]
    if crate::cpu::avx2() {
        // SAFETY: the CPU has AVX2 (the level never exceeds what the CPU has).
        return unsafe { spread_avx2(x7, e, next, fwd) };
    }
    spread_any(x7, e, next, fwd)
}

/// [`spread`] compiled for AVX2 (eight lanes, and a 32-bit multiply in one instruction).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn spread_avx2(x7: &[i32], e: &mut [i32], next: &mut [i32], fwd: bool) {
    spread_any(x7, e, next, fwd)
}

/// [`spread`] for any CPU; written so that it vectorises.
#[inline(always)]
fn spread_any(x7: &[i32], e: &mut [i32], next: &mut [i32], fwd: bool) {
    let n = x7.len();
    let (e, next) = (&mut e[..n + 2], &mut next[..n]);
    for (e, &v) in e[1..n + 1].iter_mut().zip(x7) {
        *e = v.wrapping_mul(INV7);
    }
    // In scan direction, pixel p sends `behind` to p − dir, `under` to p, `ahead` to p + dir;
    // so x receives `behind` from x + dir and `ahead` from x − dir.
    let (from_ahead, from_behind) = if fwd {
        (&e[2..n + 2], &e[..n])
    } else {
        (&e[..n], &e[2..n + 2])
    };
    for (((out, &ea), &e0), &eb) in next
        .iter_mut()
        .zip(from_ahead)
        .zip(&e[1..n + 1])
        .zip(from_behind)
    {
        *out = shares(ea)[0] + shares(e0)[1] + shares(eb)[2];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_of_seven() {
        for e in [-70000i32, -65536, -1, 0, 1, 12345, 65535, 131071] {
            assert_eq!((7 * e).wrapping_mul(INV7), e);
        }
    }

    #[test]
    fn step_matches_portable_form() {
        // Every carry the chain can hold against a spread of bases, both sides of the threshold.
        for base in (-ONE..2 * ONE)
            .step_by(97)
            .chain([HALF - 1, HALF, HALF + 1])
        {
            for carry in (-ONE..ONE).step_by(89).chain([-1, 0, 1, HALF - base]) {
                assert_eq!(
                    step(base, carry),
                    portable_step(base, carry),
                    "{base} {carry}"
                );
            }
        }
    }

    /// The spread pass as Floyd and Steinberg state it, pixel by pixel: each pixel's error
    /// `e` sends ⌊3e/16⌋ below-behind, ⌊5e/16⌋ below and what is left after those and
    /// ⌊7e/16⌋ (which the chain carries ahead) below-ahead; shares falling off the row's
    /// ends are lost.
    fn spread_by_the_book(x7: &[i32], fwd: bool) -> Vec<i32> {
        let n = x7.len() as isize;
        let mut next = vec![0; x7.len()];
        let dir = if fwd { 1 } else { -1 };
        for (p, &v) in x7.iter().enumerate() {
            let e = v / 7;
            let (behind, under) = ((3 * e) >> 4, (5 * e) >> 4);
            let ahead = e - ((7 * e) >> 4) - behind - under;
            for (to, share) in [
                (p as isize - dir, behind),
                (p as isize, under),
                (p as isize + dir, ahead),
            ] {
                if (0..n).contains(&to) {
                    next[to as usize] += share;
                }
            }
        }
        next
    }

    #[test]
    fn spread_is_the_same_on_every_path() {
        // The portable and the AVX2 spread pass (where the CPU has AVX2) against the pass
        // written out by the book, in both directions, on errors of every sign and size.
        use crate::cpu::{test_has, with_level, Level};
        let mut levels = vec![Level::Portable];
        if test_has(Level::Avx2, "fs::spread_is_the_same_on_every_path") {
            levels.push(Level::Avx2);
        }
        let mut s = 7u32;
        for n in [1usize, 2, 7, 8, 9, 31, 100] {
            let x7: Vec<i32> = (0..n)
                .map(|_| {
                    s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    7 * ((s >> 8) as i32 % (2 * ONE) - ONE)
                })
                .collect();
            for fwd in [true, false] {
                let want = spread_by_the_book(&x7, fwd);
                for &level in &levels {
                    let (mut e, mut got) = (vec![0; n + 2], vec![0; n]);
                    with_level(level, || spread(&x7, &mut e, &mut got, fwd));
                    assert_eq!(got, want, "{level:?}, {n} pixels, forward {fwd}");
                }
            }
        }
    }

    #[test]
    fn shares_sum_to_the_error() {
        for e in (-ONE..ONE).step_by(7) {
            let s = shares(e);
            assert_eq!(s.iter().sum::<i32>() + ((7 * e) >> 4), e);
        }
    }
}
