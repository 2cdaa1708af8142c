//! The one place that decides which vector loops run: the CPU's features are detected once,
//! `HALFTONE_CPU` is read once, and every hot loop asks [`level`] (or [`avx2`], [`avx512`]).
//!
//! Every vector loop gives the same bytes as the portable loop it replaces (the tests run
//! both, see [`with_level`]), so the level changes speed only.
//!
//! `HALFTONE_CPU=portable` runs the portable loops on any CPU, `HALFTONE_CPU=avx2` caps the
//! vector loops at AVX2; `native` (or unset, or any other value) uses what the CPU has.

#[cfg(feature = "lab")]
use std::sync::atomic::{AtomicU8, Ordering};
#[cfg(feature = "lab")]
use std::sync::Mutex;
use std::sync::OnceLock;

/// The vector loops a CPU can run, from none up; each level includes the ones below it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Level {
    /// Plain Rust only (what the compiler makes of it for the build's target).
    Portable,
    /// x86-64 with AVX2 (the error diffusion spread, DBS, JPEG luminance loops).
    Avx2,
    /// x86-64 with AVX-512F, AVX-512VL, AVX2 and FMA (the palette diffusion loop).
    Avx512,
}

impl Level {
    /// Every level, from the lowest.
    pub const ALL: [Level; 3] = [Level::Portable, Level::Avx2, Level::Avx512];

    /// The level's name as `HALFTONE_CPU` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Level::Portable => "portable",
            Level::Avx2 => "avx2",
            Level::Avx512 => "avx512",
        }
    }

    #[cfg(feature = "lab")]
    fn from_u8(v: u8) -> Level {
        match v {
            0 => Level::Portable,
            1 => Level::Avx2,
            _ => Level::Avx512,
        }
    }
}

/// What this CPU can run, whatever the environment says (detected on first use).
pub fn detected() -> Level {
    static DETECTED: OnceLock<Level> = OnceLock::new();
    *DETECTED.get_or_init(detect)
}

#[cfg(target_arch = "x86_64")]
fn detect() -> Level {
    use std::arch::is_x86_feature_detected as has;
    if has!("avx512f") && has!("avx512vl") && has!("avx2") && has!("fma") {
        Level::Avx512
    } else if has!("avx2") {
        Level::Avx2
    } else {
        Level::Portable
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn detect() -> Level {
    Level::Portable
}

/// The level `HALFTONE_CPU` asks for, capped at [`detected`] (read on first use).
fn from_env() -> Level {
    static ENV: OnceLock<Level> = OnceLock::new();
    *ENV.get_or_init(|| {
        let asked = match std::env::var("HALFTONE_CPU").as_deref() {
            Ok("portable") => Level::Portable,
            Ok("avx2") => Level::Avx2,
            _ => Level::Avx512,
        };
        asked.min(detected())
    })
}

/// A level set by [`with_level`], or `NONE`. Only with the measuring tools (feature `lab`,
/// which the command line and the tests build): a library built without them keeps no
/// process-wide state but the CPU's and the environment's level, each read once.
#[cfg(feature = "lab")]
static OVERRIDE: AtomicU8 = AtomicU8::new(NONE);
#[cfg(feature = "lab")]
const NONE: u8 = u8::MAX;
/// Held while a [`with_level`] closure runs, so that two never overlap.
#[cfg(feature = "lab")]
static SCOPE: Mutex<()> = Mutex::new(());

/// The vector loops to run now: [`with_level`]'s level inside its closure, otherwise
/// `HALFTONE_CPU`'s, never above what the CPU has.
pub fn level() -> Level {
    #[cfg(feature = "lab")]
    match OVERRIDE.load(Ordering::Relaxed) {
        NONE => {}
        v => return Level::from_u8(v).min(detected()),
    }
    from_env()
}

/// Whether the AVX2 loops run now.
pub fn avx2() -> bool {
    level() >= Level::Avx2
}

/// Whether the AVX-512 loops run now.
pub fn avx512() -> bool {
    level() >= Level::Avx512
}

/// Runs `f` with the vector loops capped at `level` (and at what the CPU has), in every
/// thread, then restores the level from the environment: how the tests and benchmarks run the
/// portable and the vector loops of one build side by side in one process.
///
/// Calls from several threads take turns (the level is the whole process's while `f` runs);
/// a call inside `f` would wait for itself forever, so do not nest them. Work running at the
/// same time outside `f` may run at `f`'s level too, which changes its speed, never its bytes.
#[cfg(feature = "lab")]
pub fn with_level<R>(level: Level, f: impl FnOnce() -> R) -> R {
    let _turn = SCOPE.lock().unwrap_or_else(|e| e.into_inner());
    /// Restores the level when `f` returns or panics.
    struct Restore;
    impl Drop for Restore {
        fn drop(&mut self) {
            OVERRIDE.store(NONE, Ordering::Relaxed);
        }
    }
    OVERRIDE.store(level as u8, Ordering::Relaxed);
    let _restore = Restore;
    f()
}

/// For the unit tests that compare a vector loop with the portable one: whether this CPU has
/// `level`. A CPU without it cannot run that loop at all (no tool installs an instruction set),
/// so the missing path is said on standard error, past the test harness's capture, and the
/// comparison is skipped; `.ci/run` prints which vector levels its machine has first,
/// so a run that covered fewer paths shows it.
#[cfg(test)]
pub(crate) fn test_has(level: Level, test: &str) -> bool {
    use std::io::Write;
    if detected() >= level {
        return true;
    }
    let _ = writeln!(
        std::io::stderr().lock(),
        "SKIPPED {test}: this CPU has no {} (it has {}), so only the portable loop was tested",
        level.name(),
        detected().name()
    );
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn with_level_caps_and_restores() {
        let restored = || {
            let _turn = SCOPE.lock().unwrap_or_else(|e| e.into_inner());
            OVERRIDE.load(Ordering::Relaxed) == NONE
        };
        with_level(Level::Portable, || {
            assert_eq!(level(), Level::Portable);
            assert!(!avx2() && !avx512());
            // Seen by the other threads too (rayon's workers run the loops).
            let seen = std::thread::spawn(level).join().unwrap();
            assert_eq!(seen, Level::Portable);
        });
        assert!(restored());
        with_level(Level::Avx512, || assert_eq!(level(), detected()));
        let caught = std::panic::catch_unwind(|| with_level(Level::Portable, || panic!("x")));
        assert!(caught.is_err());
        assert!(restored(), "a panic inside restores the level");
    }

    #[test]
    fn levels_are_ordered_and_named() {
        assert!(Level::Portable < Level::Avx2 && Level::Avx2 < Level::Avx512);
        for l in Level::ALL {
            assert_eq!(Level::from_u8(l as u8), l);
        }
        assert_eq!(Level::ALL.map(Level::name), ["portable", "avx2", "avx512"]);
    }
}
