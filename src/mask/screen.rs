//! AM screens described by a printer's numbers: device resolution (dpi), screen frequency
//! (lines per inch), screen angle and spot function.
//!
//! Unlike rational-tangent screens (a cell of whole pixels repeated, as Ghostscript's
//! `.genordered` builds them), the screen here is exact at any frequency and angle:
//!
//! 1. Every pixel centre is rotated into screen coordinates `(u, v)`, measured in cells:
//!    `u = ( X cos θ + Y sin θ)/p`, `v = (−X sin θ + Y cos θ)/p`, with `X, Y` the centre in
//!    pixels, Y pointing up (PostScript's convention: θ counter-clockwise from the x axis)
//!    and `p = dpi/lpi` the cell period in pixels. The pixel belongs to cell
//!    `(⌊u⌋, ⌊v⌋)` and sits at spot coordinates `x = 2·frac(u) − 1`, `y = 2·frac(v) − 1`.
//! 2. Inside its own cell a pixel is ranked by the spot function's value (the highest value
//!    takes ink first, so a round dot grows from the centre); ties go by position.
//! 3. A cell of `n` pixels would give only `n + 1` tones, and cells differ in `n` at
//!    irrational angles. Each cell therefore gets a stagger `d ∈ [0, 1)` from a 16×16 Bayer
//!    order over cell indices, and the pixel of rank `r` gets the ink threshold
//!    `t = (r + d)/n`. A cell then holds `⌈a·n − d⌉` inked pixels at ink coverage `a`, which
//!    averages to exactly `a·n` over the 256 staggers: 256 sub-levels between whole-pixel
//!    steps, and the tone is right for every cell whatever its `n`.
//!
//! Thresholds are stored in 16 bits (`⌊t·65536⌋`). A pixel's threshold depends only on its
//! position, so rows can be computed independently ([`Screen::threshold_row`]).

use crate::fmath as fm;
use std::f64::consts::PI;

use crate::error::{Error, Result};

/// The 21 standard spot functions of the PDF specification (ISO 32000-1:2008 §8.4.2.3,
/// Table 130 "Predefined spot functions"), by their PDF names. `x, y ∈ [−1, 1]`; the
/// highest value takes ink first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Spot {
    /// `1 − (x² + y²)`.
    SimpleDot,
    /// `x² + y² − 1`.
    InvertedSimpleDot,
    /// `(sin 360x + sin 360y)/2`.
    DoubleDot,
    /// `−(sin 360x + sin 360y)/2`.
    InvertedDoubleDot,
    /// `(cos 180x + cos 180y)/2`.
    CosineDot,
    /// `(sin 180x + sin 360y)/2`.
    Double,
    /// `−(sin 180x + sin 360y)/2`.
    InvertedDouble,
    /// `−|y|`.
    Line,
    /// `x`.
    LineX,
    /// `y`.
    LineY,
    /// A round dot that turns into a round hole past 50%.
    Round,
    /// An elliptical dot (Adobe's), chaining at 30% and 70%.
    Ellipse,
    /// `1 − (x² + 0.9y²)`.
    EllipseA,
    /// `x² + 0.9y² − 1`.
    InvertedEllipseA,
    /// `1 − √(x² + 0.625y²)`.
    EllipseB,
    /// `1 − (0.9x² + y²)`.
    EllipseC,
    /// `0.9x² + y² − 1`.
    InvertedEllipseC,
    /// `−max(|x|, |y|)`.
    Square,
    /// `−min(|x|, |y|)`.
    Cross,
    /// `(0.9|x| + |y|)/2`.
    Rhomboid,
    /// Round in the highlights, square at mid-tones, round holes in the shadows.
    Diamond,
}

impl Spot {
    /// Every spot function, in the order of the PDF specification's table.
    pub const ALL: [Spot; 21] = [
        Spot::SimpleDot,
        Spot::InvertedSimpleDot,
        Spot::DoubleDot,
        Spot::InvertedDoubleDot,
        Spot::CosineDot,
        Spot::Double,
        Spot::InvertedDouble,
        Spot::Line,
        Spot::LineX,
        Spot::LineY,
        Spot::Round,
        Spot::Ellipse,
        Spot::EllipseA,
        Spot::InvertedEllipseA,
        Spot::EllipseB,
        Spot::EllipseC,
        Spot::InvertedEllipseC,
        Spot::Square,
        Spot::Cross,
        Spot::Rhomboid,
        Spot::Diamond,
    ];

    /// The PDF name, e.g. `SimpleDot`.
    pub fn name(self) -> &'static str {
        match self {
            Spot::SimpleDot => "SimpleDot",
            Spot::InvertedSimpleDot => "InvertedSimpleDot",
            Spot::DoubleDot => "DoubleDot",
            Spot::InvertedDoubleDot => "InvertedDoubleDot",
            Spot::CosineDot => "CosineDot",
            Spot::Double => "Double",
            Spot::InvertedDouble => "InvertedDouble",
            Spot::Line => "Line",
            Spot::LineX => "LineX",
            Spot::LineY => "LineY",
            Spot::Round => "Round",
            Spot::Ellipse => "Ellipse",
            Spot::EllipseA => "EllipseA",
            Spot::InvertedEllipseA => "InvertedEllipseA",
            Spot::EllipseB => "EllipseB",
            Spot::EllipseC => "EllipseC",
            Spot::InvertedEllipseC => "InvertedEllipseC",
            Spot::Square => "Square",
            Spot::Cross => "Cross",
            Spot::Rhomboid => "Rhomboid",
            Spot::Diamond => "Diamond",
        }
    }

    /// Looks a spot function up by its PDF name, case-insensitively, with or without
    /// hyphens or underscores (`round`, `SimpleDot`, `inverted-simple-dot`).
    pub fn from_name(name: &str) -> Result<Spot> {
        let key: String = name
            .chars()
            .filter(|c| !matches!(c, '-' | '_' | ' '))
            .collect::<String>()
            .to_ascii_lowercase();
        Spot::ALL
            .iter()
            .copied()
            .find(|s| s.name().to_ascii_lowercase() == key)
            .ok_or_else(|| {
                let names: Vec<&str> = Spot::ALL.iter().map(|s| s.name()).collect();
                Error::Invalid(format!(
                    "unknown spot function '{name}' (known: {})",
                    names.join(", ")
                ))
            })
    }

    /// The spot function's value at `(x, y)`, both in `[−1, 1]`.
    #[inline]
    pub fn value(self, x: f64, y: f64) -> f64 {
        let (ax, ay) = (x.abs(), y.abs());
        let deg = PI / 180.0;
        match self {
            Spot::SimpleDot => 1.0 - (x * x + y * y),
            Spot::InvertedSimpleDot => x * x + y * y - 1.0,
            Spot::DoubleDot => (fm::sin(x * 360.0 * deg) + fm::sin(y * 360.0 * deg)) / 2.0,
            Spot::InvertedDoubleDot => -(fm::sin(x * 360.0 * deg) + fm::sin(y * 360.0 * deg)) / 2.0,
            Spot::CosineDot => (fm::cos(x * 180.0 * deg) + fm::cos(y * 180.0 * deg)) / 2.0,
            Spot::Double => (fm::sin(x * 180.0 * deg) + fm::sin(y * 360.0 * deg)) / 2.0,
            Spot::InvertedDouble => -(fm::sin(x * 180.0 * deg) + fm::sin(y * 360.0 * deg)) / 2.0,
            Spot::Line => -ay,
            Spot::LineX => x,
            Spot::LineY => y,
            Spot::Round => {
                if ax + ay <= 1.0 {
                    1.0 - (x * x + y * y)
                } else {
                    (ax - 1.0).powi(2) + (ay - 1.0).powi(2) - 1.0
                }
            }
            Spot::Ellipse => {
                let w = 3.0 * ax + 4.0 * ay - 3.0;
                if w < 0.0 {
                    1.0 - (x * x + (ay / 0.75).powi(2)) / 4.0
                } else if w > 1.0 {
                    ((1.0 - ax).powi(2) + ((1.0 - ay) / 0.75).powi(2)) / 4.0 - 1.0
                } else {
                    0.5 - w
                }
            }
            Spot::EllipseA => 1.0 - (x * x + 0.9 * y * y),
            Spot::InvertedEllipseA => x * x + 0.9 * y * y - 1.0,
            Spot::EllipseB => 1.0 - (x * x + 0.625 * y * y).sqrt(),
            Spot::EllipseC => 1.0 - (0.9 * x * x + y * y),
            Spot::InvertedEllipseC => 0.9 * x * x + y * y - 1.0,
            Spot::Square => -ax.max(ay),
            Spot::Cross => -ax.min(ay),
            Spot::Rhomboid => (0.9 * ax + ay) / 2.0,
            Spot::Diamond => {
                let s = ax + ay;
                if s <= 0.75 {
                    1.0 - (x * x + y * y)
                } else if s <= 1.23 {
                    1.0 - (0.85 * ax + ay)
                } else {
                    (ax - 1.0).powi(2) + (ay - 1.0).powi(2) - 1.0
                }
            }
        }
    }
}

/// `x.floor()` for |x| < 2⁶², without the libm call that baseline x86-64 makes of it (no
/// SSE4.1 `roundsd`): the screen calls it twice a pixel. Exact: truncation, then one down
/// for negative non-integers.
#[inline]
fn floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

/// `x.round()` (half away from zero) for |x| < 2⁶², without the libm call. Exact: `x − t`
/// is exact for the truncation `t`.
#[inline]
fn round(x: f64) -> f64 {
    let t = x as i64 as f64;
    let d = x - t;
    if d >= 0.5 {
        t + 1.0
    } else if d <= -0.5 {
        t - 1.0
    } else {
        t
    }
}

/// 1.5 × 2⁵²: `x + M` for |x| < 2⁵¹ lies where doubles are whole numbers, so the sum rounds
/// `x` to the nearest integer (ties to even) and `(x + M) − M` is that integer, exactly.
const MAGIC: f64 = 6_755_399_441_055_744.0;

/// [`floor`] without conversions (a select, so a loop of it runs on vectors) for
/// |x| < 2⁵¹: the nearest integer, one down when it lies above `x`.
#[inline(always)]
fn floor_rne(x: f64) -> f64 {
    let r = (x + MAGIC) - MAGIC;
    if r > x {
        r - 1.0
    } else {
        r
    }
}

/// [`round`] (half away from zero) without conversions for |x| < 2⁵¹: the nearest
/// integer, ties to even, moved away from zero at a tie. `x − r` is exact (`r` is a whole
/// number within ½ of `x`).
#[inline(always)]
fn round_rne(x: f64) -> f64 {
    let r = (x + MAGIC) - MAGIC;
    let d = x - r;
    if d == 0.5 && x > 0.0 {
        r + 1.0
    } else if d == -0.5 && x < 0.0 {
        r - 1.0
    } else {
        r
    }
}

/// A whole number |r| < 2³¹ as an i32, from the low bits of `r + MAGIC` (whose bit pattern
/// is MAGIC's, whose low 32 bits are zero, plus `r`).
#[inline(always)]
fn low_i32(r: f64) -> i32 {
    (r + MAGIC).to_bits() as u32 as i32
}

/// What a screen is asked for, in the printer's numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenSpec {
    /// Device resolution, dots per inch.
    pub dpi: f64,
    /// Screen frequency, lines per inch.
    pub lpi: f64,
    /// Screen angle in degrees, counter-clockwise from the x axis with y up.
    pub angle: f64,
    /// Dot shape.
    pub spot: Spot,
}

/// The 16×16 Bayer index matrix (recursive definition), the order of the cells' staggers.
fn bayer16(i: usize, j: usize) -> u32 {
    let mut v = 0u32;
    for bit in 0..4 {
        let x = (i >> bit) & 1;
        let y = (j >> bit) & 1;
        // 2×2 Bayer: [[0, 2], [3, 1]].
        let b = match (x, y) {
            (0, 0) => 0,
            (1, 0) => 2,
            (0, 1) => 3,
            _ => 1,
        };
        // M₂ₙ = [[4M, 4M+2], [4M+3, 4M+1]]: the finest bit gives the top digit.
        v |= b << (2 * (3 - bit));
    }
    v
}

/// An exact AM screen: the threshold of every device pixel.
#[derive(Clone, Debug)]
pub struct Screen {
    spec: ScreenSpec,
    /// Cell period in pixels.
    period: f64,
    cos: f64,
    sin: f64,
}

/// The pixels of one cell, ranked: `(spot value, position key)` in ink order.
#[derive(Debug)]
struct CellRanks {
    order: Vec<(f64, u64)>,
    stagger: f64,
}

/// Cells already ranked, shared by the rows of one band. A pixel's threshold never depends
/// on what the cache holds, only on its position.
///
/// Cells live in a vector, found through an open-addressed table keyed by a multiplicative
/// hash of the cell index (deterministic, a few instructions: std's SipHash was most of the
/// screen's time), with the last cell looked up remembered, since neighbouring pixels of a
/// row mostly share a cell.
#[derive(Debug, Default)]
pub struct CellCache {
    cells: Vec<((i64, i64), CellRanks)>,
    /// Open-addressed slots: index into `cells` + 1 (0 = empty); length a power of two.
    slots: Vec<u32>,
    last: Option<usize>,
}

impl CellCache {
    /// An empty cache.
    pub fn new() -> CellCache {
        CellCache::default()
    }

    /// Slot of a cell index in a table of `mask + 1` slots (Fibonacci hashing).
    #[inline]
    fn home(cell: (i64, i64), mask: usize) -> usize {
        let h = (cell.0 as u64)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .rotate_left(29)
            ^ (cell.1 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        (h.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 32) as usize & mask
    }

    /// The ranks of `cell`, ranking it with `rank` on a miss.
    #[inline]
    fn get(&mut self, cell: (i64, i64), rank: impl FnOnce() -> CellRanks) -> &CellRanks {
        if let Some(i) = self.last {
            if self.cells[i].0 == cell {
                return &self.cells[i].1;
            }
        }
        if self.cells.len() >= CACHE_LIMIT {
            self.cells.clear();
            self.slots.clear();
            self.last = None;
        }
        if self.slots.is_empty() {
            self.slots = vec![0; 1024];
        }
        let mut mask = self.slots.len() - 1;
        let mut at = Self::home(cell, mask);
        loop {
            match self.slots[at] {
                0 => break,
                i if self.cells[i as usize - 1].0 == cell => {
                    let i = i as usize - 1;
                    self.last = Some(i);
                    return &self.cells[i].1;
                }
                _ => at = (at + 1) & mask,
            }
        }
        // A miss: rank the cell, growing the table to stay under half full.
        self.cells.push((cell, rank()));
        let i = self.cells.len() - 1;
        if 2 * self.cells.len() > self.slots.len() {
            self.slots = vec![0; self.slots.len() * 2];
            mask = self.slots.len() - 1;
            for (k, (c, _)) in self.cells.iter().enumerate() {
                let mut a = Self::home(*c, mask);
                while self.slots[a] != 0 {
                    a = (a + 1) & mask;
                }
                self.slots[a] = k as u32 + 1;
            }
        } else {
            self.slots[at] = i as u32 + 1;
        }
        self.last = Some(i);
        &self.cells[i].1
    }
}

/// Cache size (cells) past which it is emptied.
const CACHE_LIMIT: usize = 1 << 16;

/// Largest margin ([`Screen::halo`], pixels) for which a band is screened from one located
/// region; past it (cells of more than ~20 pixels a side at 45°) the margin would cost more
/// than ranking cell by cell.
const REGION_HALO_LIMIT: usize = 32;

/// Bias of the spot key in a sort entry: spot values lie in [−1, 1], keys in ±2²⁴.
const SPOT_BIAS: i64 = 1 << 30;

impl Screen {
    /// A screen for `spec`. Errors when the numbers cannot make a screen (non-positive or
    /// non-finite, or a cell smaller than 2 pixels a side).
    pub fn new(spec: ScreenSpec) -> Result<Screen> {
        if !(spec.dpi.is_finite() && spec.dpi > 0.0) {
            return Err(Error::Invalid(format!(
                "--dpi {}: must be a positive number",
                spec.dpi
            )));
        }
        if !(spec.lpi.is_finite() && spec.lpi > 0.0) {
            return Err(Error::Invalid(format!(
                "--lpi {}: must be a positive number",
                spec.lpi
            )));
        }
        if !spec.angle.is_finite() {
            return Err(Error::Invalid(format!(
                "--angle {}: must be a number of degrees",
                spec.angle
            )));
        }
        let period = spec.dpi / spec.lpi;
        if period < 2.0 {
            return Err(Error::Invalid(format!(
                "--lpi {} at {} dpi gives a cell of {:.2} pixels: it must be at least 2 (lower --lpi)",
                spec.lpi, spec.dpi, period
            )));
        }
        if period > 4096.0 {
            return Err(Error::Invalid(format!(
                "--lpi {} at {} dpi gives a cell of {:.0} pixels: at most 4096",
                spec.lpi, spec.dpi, period
            )));
        }
        let a = spec.angle.to_radians();
        Ok(Screen {
            spec,
            period,
            cos: fm::cos(a),
            sin: fm::sin(a),
        })
    }

    /// What was asked for.
    pub fn spec(&self) -> ScreenSpec {
        self.spec
    }

    /// Cell period in device pixels (`dpi/lpi`).
    pub fn period(&self) -> f64 {
        self.period
    }

    /// Device pixels a cell (`period²`, on average).
    pub fn pixels_per_cell(&self) -> f64 {
        self.period * self.period
    }

    /// The two cell vectors in device pixels, x right and y down (the image's axes).
    pub fn cell_vectors(&self) -> [(f64, f64); 2] {
        let p = self.period;
        [
            (p * self.cos, -p * self.sin),
            (-p * self.sin, -p * self.cos),
        ]
    }

    /// Screen coordinates (in cells) of the centre of pixel `(x, y)`.
    #[inline]
    fn uv(&self, x: i64, y: i64) -> (f64, f64) {
        let px = x as f64 + 0.5;
        // Y up: the image's row y is at −(y + ½).
        let py = -(y as f64 + 0.5);
        let u = (px * self.cos + py * self.sin) / self.period;
        let v = (-px * self.sin + py * self.cos) / self.period;
        (u, v)
    }

    /// Cell index and spot value of pixel `(x, y)`.
    #[inline]
    fn locate(&self, x: i64, y: i64) -> ((i64, i64), f64) {
        let (u, v) = self.uv(x, y);
        let (fu, fv) = (floor(u), floor(v));
        let sx = 2.0 * (u - fu) - 1.0;
        let sy = 2.0 * (v - fv) - 1.0;
        // Rounded to 2⁻²⁴ so that positions which tie exactly (a symmetric spot's mirror
        // images) tie in every cell whatever the rounding of u and v, and the position key
        // decides: then a screen that repeats on the grid repeats exactly.
        let s = self.spec.spot.value(sx, sy);
        (
            (fu as i64, fv as i64),
            round(s * 16_777_216.0) / 16_777_216.0,
        )
    }

    /// Position key for ties: row-major over the device plane (offset so it is positive).
    #[inline]
    fn key(x: i64, y: i64) -> u64 {
        (((y + (1 << 31)) as u64) << 32) | ((x + (1 << 31)) as u64 & 0xFFFF_FFFF)
    }

    /// The pixel of a position key.
    #[inline]
    fn unkey(key: u64) -> (i64, i64) {
        (
            (key & 0xFFFF_FFFF) as i64 - (1 << 31),
            (key >> 32) as i64 - (1 << 31),
        )
    }

    /// Ranks the pixels of cell `(i, j)`.
    fn rank_cell(&self, cell: (i64, i64)) -> CellRanks {
        let (i, j) = (cell.0 as f64, cell.1 as f64);
        // The cell's corners in pixel coordinates (x right, y down).
        let corner = |a: f64, b: f64| {
            let (u, v) = (a * self.period, b * self.period);
            let px = u * self.cos - v * self.sin;
            let py = u * self.sin + v * self.cos;
            (px, -py)
        };
        let cs = [
            corner(i, j),
            corner(i + 1.0, j),
            corner(i, j + 1.0),
            corner(i + 1.0, j + 1.0),
        ];
        let x0 = cs.iter().map(|c| c.0).fold(f64::INFINITY, f64::min).floor() as i64 - 1;
        let x1 = cs
            .iter()
            .map(|c| c.0)
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil() as i64
            + 1;
        // Rows whose pixel centres (y + ½) can lie in the cell, with a hair of margin for
        // rounding: `locate` decides membership, so a margin only costs a try.
        const EPS: f64 = 1e-6;
        let ymin = cs.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
        let ymax = cs.iter().map(|c| c.1).fold(f64::NEG_INFINITY, f64::max);
        let y0 = (ymin - 0.5 - EPS).ceil() as i64;
        let y1 = (ymax - 0.5 + EPS).floor() as i64;
        let mut order = Vec::with_capacity((self.period * self.period) as usize + 8);
        let p = self.period;
        for y in y0..=y1 {
            // The span of this row inside the cell's parallelogram (`i ≤ u ≤ i + 1` and
            // `j ≤ v ≤ j + 1` solved for the pixel centre's x), with the same hair of
            // margin: far fewer pixels to try than the bounding box at an angle, and
            // `locate` still decides membership, so the ranks are the same.
            let py = -(y as f64 + 0.5);
            let (mut lo, mut hi) = (x0 as f64, x1 as f64 + 1.0);
            if self.cos.abs() > 1e-9 {
                let a = (i * p - py * self.sin) / self.cos;
                let b = ((i + 1.0) * p - py * self.sin) / self.cos;
                lo = lo.max(a.min(b));
                hi = hi.min(a.max(b));
            }
            if self.sin.abs() > 1e-9 {
                let a = (py * self.cos - j * p) / self.sin;
                let b = (py * self.cos - (j + 1.0) * p) / self.sin;
                lo = lo.max(a.min(b));
                hi = hi.min(a.max(b));
            }
            let xs = ((lo - 0.5 - EPS).ceil() as i64).max(x0);
            let xe = ((hi - 0.5 + EPS).floor() as i64).min(x1);
            for x in xs..=xe {
                let (c, s) = self.locate(x, y);
                if c == cell {
                    order.push((s, Self::key(x, y)));
                }
            }
        }
        order.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        CellRanks {
            order,
            stagger: Self::stagger(cell),
        }
    }

    /// The stagger of a cell: its place in the 16×16 Bayer order of cells, centred.
    fn stagger(cell: (i64, i64)) -> f64 {
        (bayer16(
            cell.0.rem_euclid(16) as usize,
            cell.1.rem_euclid(16) as usize,
        ) as f64
            + 0.5)
            / 256.0
    }

    /// The ink threshold of pixel `(x, y)` in 0..1: the pixel takes ink when the ink
    /// coverage asked for exceeds it.
    pub fn threshold(&self, x: i64, y: i64, cache: &mut CellCache) -> f64 {
        let (cell, s) = self.locate(x, y);
        let ranks = cache.get(cell, || self.rank_cell(cell));
        let key = Self::key(x, y);
        let r = ranks
            .order
            .partition_point(|&(v, k)| v > s || (v == s && k < key));
        (r as f64 + ranks.stagger) / ranks.order.len() as f64
    }

    /// 16-bit thresholds (`⌊t·65536⌋`) of row `y`, pixels `x0 .. x0 + out.len()`.
    pub fn threshold_row(&self, y: i64, x0: i64, out: &mut [u16], cache: &mut CellCache) {
        for (k, o) in out.iter_mut().enumerate() {
            let t = self.threshold(x0 + k as i64, y, cache);
            // t ≥ 0, so truncation is the floor.
            *o = ((t * 65536.0) as u32).min(65535) as u16;
        }
    }

    /// Pixels around a band (rows above and below, columns left and right) that hold every
    /// pixel of any cell reaching the band: a cell's pixel centres lie in its
    /// parallelogram, which spans `p(|cos θ| + |sin θ|)` pixels along x and along y; two
    /// more for the rounding of `u` and `v` at its edges.
    fn halo(&self) -> usize {
        (self.period * (self.cos.abs() + self.sin.abs())).ceil() as usize + 2
    }

    /// Bytes of scratch [`Screen::threshold_band`] uses for a band of `rows × width`.
    pub fn band_scratch_bytes(&self, rows: usize, width: usize) -> usize {
        let h = self.halo();
        if h > REGION_HALO_LIMIT {
            return width.saturating_mul(rows).saturating_mul(2);
        }
        // Cell index pair and spot key (12 bytes), then the sort entry (8 bytes), a pixel.
        (rows + 2 * h)
            .saturating_mul(width + 2 * h)
            .saturating_mul(20)
    }

    /// 16-bit thresholds of rows `y0 .. y0 + rows`, pixels `0 .. width`, row-major into
    /// `out` (`width × rows`): the values of [`Screen::threshold_row`].
    ///
    /// Every pixel of the band and of a margin around it ([`Screen::halo`], wide enough to
    /// hold the whole of every cell reaching the band) is located once, row by row with
    /// the spot function chosen once; the pixels are then grouped by cell (a counting
    /// sort), each cell reaching the band is sorted by `locate`'s order (spot value, then
    /// position), and its band pixels take their thresholds from their rank. The same
    /// arithmetic as [`Screen::threshold`] on the same pixels, so the same thresholds.
    /// Screens whose cells are too large for a margin (periods past ~20 pixels at 45°)
    /// rank cell by cell instead.
    pub fn threshold_band(&self, y0: i64, rows: usize, width: usize, out: &mut [u16]) {
        assert_eq!(out.len(), width * rows, "out holds width × rows thresholds");
        if width == 0 || rows == 0 {
            return;
        }
        let h = self.halo();
        let (rw, rh) = (width + 2 * h, rows + 2 * h);
        // Region positions in sort entries: a row in the high bits, the column in `shift`.
        let shift = usize::BITS - rw.leading_zeros();
        // Cell indices are 32-bit, and positions too: pages past 2³⁰ pixels a side, or
        // bands of more than 2³² positions, take the cell-by-cell path.
        let far = y0.unsigned_abs() as u128 + (rows + width + 2 * h) as u128 >= 1 << 30;
        let wide = (rh as u128) << shift > 1 << 32;
        if h > REGION_HALO_LIMIT || far || wide {
            return self.threshold_band_cells(y0, rows, width, out);
        }
        let (rx0, ry0) = (-(h as i64), y0 - h as i64);
        let n = rw * rh;
        let mut ci = vec![0i32; n];
        let mut cj = vec![0i32; n];
        let mut sk = vec![0i32; n];
        for r in 0..rh {
            let span = r * rw..(r + 1) * rw;
            self.locate_row(
                ry0 + r as i64,
                rx0,
                &mut ci[span.clone()],
                &mut cj[span.clone()],
                &mut sk[span],
            );
        }
        // Cells by column i, then row j: each column's range of j among the region's
        // pixels, then a dense index over those ranges.
        let (imin, imax) = ci
            .iter()
            .fold((i32::MAX, i32::MIN), |(a, b), &i| (a.min(i), b.max(i)));
        let columns = (imax - imin) as usize + 1;
        let mut jr = vec![(i32::MAX, i32::MIN); columns];
        for (&i, &j) in ci.iter().zip(&cj) {
            let e = &mut jr[(i - imin) as usize];
            *e = (e.0.min(j), e.1.max(j));
        }
        let mut first = Vec::with_capacity(columns + 1);
        let mut total = 0usize;
        for &(lo, hi) in &jr {
            first.push(total);
            if lo <= hi {
                total += (hi - lo) as usize + 1;
            }
        }
        // Cell id of each pixel (into `ci`), pixels a cell, and whether a cell reaches
        // the band.
        let mut count = vec![0u32; total + 1];
        let mut reaches = vec![false; total];
        for (r, (ids, js)) in ci.chunks_exact_mut(rw).zip(cj.chunks_exact(rw)).enumerate() {
            for (i, &j) in ids.iter_mut().zip(js) {
                let c = (*i - imin) as usize;
                let id = first[c] + (j - jr[c].0) as usize;
                *i = id as i32;
                count[id + 1] += 1;
            }
            if (h..h + rows).contains(&r) {
                for &id in &ids[h..h + width] {
                    reaches[id as usize] = true;
                }
            }
        }
        for c in 1..=total {
            count[c] += count[c - 1];
        }
        // Sort entries: the spot key descending, then the position ascending, in one u64.
        // The position is (row << shift) | column: row-major, as `key` orders the page.
        let mut entries = vec![0u64; n];
        let mut next = count.clone();
        for (r, (ids, ss)) in ci.chunks_exact(rw).zip(sk.chunks_exact(rw)).enumerate() {
            let row = (r as u64) << shift;
            for (col, (&id, &s)) in ids.iter().zip(ss).enumerate() {
                let slot = &mut next[id as usize];
                entries[*slot as usize] = ((SPOT_BIAS - s as i64) as u64) << 32 | row | col as u64;
                *slot += 1;
            }
        }
        let cols = (1u64 << shift) - 1;
        for id in 0..total {
            if !reaches[id] {
                continue;
            }
            let cell = &mut entries[count[id] as usize..count[id + 1] as usize];
            cell.sort_unstable();
            // The column holding this id (the last whose first id is at most it: an empty
            // column shares its first id with the next).
            let c = first.partition_point(|&f| f <= id) - 1;
            let (i, j) = (
                imin as i64 + c as i64,
                jr[c].0 as i64 + (id - first[c]) as i64,
            );
            let stagger = Self::stagger((i, j));
            let len = cell.len() as f64;
            for (r, &e) in cell.iter().enumerate() {
                let (row, col) = (((e & 0xFFFF_FFFF) >> shift) as usize, (e & cols) as usize);
                if row < h || row >= h + rows || col < h || col >= h + width {
                    continue;
                }
                let t = (r as f64 + stagger) / len;
                out[(row - h) * width + (col - h)] = ((t * 65536.0) as u32).min(65535) as u16;
            }
        }
    }

    /// Cell indices and spot keys (the spot value in units of 2⁻²⁴, which `locate` rounds
    /// it to) of pixels `x0 ..` of row `y`: `locate`'s arithmetic, operation for
    /// operation, with the spot function chosen once for the row.
    fn locate_row(&self, y: i64, x0: i64, ci: &mut [i32], cj: &mut [i32], sk: &mut [i32]) {
        macro_rules! each_spot {
            ($($s:ident),*) => {
                match self.spec.spot {
                    $(Spot::$s => self.locate_row_with(y, x0, ci, cj, sk, |x, y| Spot::$s.value(x, y)),)*
                }
            };
        }
        each_spot!(
            SimpleDot,
            InvertedSimpleDot,
            DoubleDot,
            InvertedDoubleDot,
            CosineDot,
            Double,
            InvertedDouble,
            Line,
            LineX,
            LineY,
            Round,
            Ellipse,
            EllipseA,
            InvertedEllipseA,
            EllipseB,
            EllipseC,
            InvertedEllipseC,
            Square,
            Cross,
            Rhomboid,
            Diamond
        )
    }

    #[inline(always)]
    fn locate_row_with(
        &self,
        y: i64,
        x0: i64,
        ci: &mut [i32],
        cj: &mut [i32],
        sk: &mut [i32],
        spot: impl Fn(f64, f64) -> f64,
    ) {
        // As `uv`: py·sin and py·cos are the same products for the whole row.
        let py = -(y as f64 + 0.5);
        let (ps, pc) = (py * self.sin, py * self.cos);
        let (cos, sin, p) = (self.cos, self.sin, self.period);
        let n = ci.len().min(cj.len()).min(sk.len());
        // Branch-free (selects only), so that the loop runs on vectors of f64.
        for k in 0..n {
            let px = (x0 + k as i64) as f64 + 0.5;
            let u = (px * cos + ps) / p;
            let v = (-px * sin + pc) / p;
            let (fu, fv) = (floor_rne(u), floor_rne(v));
            let value = spot(2.0 * (u - fu) - 1.0, 2.0 * (v - fv) - 1.0);
            ci[k] = low_i32(fu);
            cj[k] = low_i32(fv);
            sk[k] = low_i32(round_rne(value * 16_777_216.0));
        }
    }

    /// [`Screen::threshold_band`] cell by cell, for screens with large cells: each cell
    /// whose pixels reach the band is ranked once and writes its pixels' thresholds
    /// straight from its ranking (a pixel's rank is its index there).
    fn threshold_band_cells(&self, y0: i64, rows: usize, width: usize, out: &mut [u16]) {
        let p = self.period;
        // The band's pixel centres span this rectangle (x right, Y up).
        let (xa, xb) = (0.5, width as f64 - 0.5);
        let (ya, yb) = (-(y0 as f64 + rows as f64 - 0.5), -(y0 as f64 + 0.5));
        let u = |x: f64, y: f64| (x * self.cos + y * self.sin) / p;
        let v = |x: f64, y: f64| (-x * self.sin + y * self.cos) / p;
        let rect = [(xa, ya), (xb, ya), (xb, yb), (xa, yb)];
        let us: Vec<f64> = rect.iter().map(|&(x, y)| u(x, y)).collect();
        let i0 = us.iter().copied().fold(f64::INFINITY, f64::min).floor() as i64 - 1;
        let i1 = us.iter().copied().fold(f64::NEG_INFINITY, f64::max).floor() as i64 + 1;
        for i in i0..=i1 {
            // The rectangle clipped to the strip i ≤ u ≤ i + 1 (Sutherland–Hodgman); the
            // cells of this column that can hold band pixels lie within its v range.
            let mut poly: Vec<(f64, f64)> = rect.to_vec();
            for (bound, keep_above) in [(i as f64, true), (i as f64 + 1.0, false)] {
                let inside = |q: (f64, f64)| {
                    let d = u(q.0, q.1) - bound;
                    if keep_above {
                        d >= 0.0
                    } else {
                        d <= 0.0
                    }
                };
                let mut next = Vec::with_capacity(poly.len() + 2);
                for k in 0..poly.len() {
                    let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
                    let (ia, ib) = (inside(a), inside(b));
                    if ia {
                        next.push(a);
                    }
                    if ia != ib {
                        let (ua, ub) = (u(a.0, a.1), u(b.0, b.1));
                        let t = (bound - ua) / (ub - ua);
                        next.push((a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)));
                    }
                }
                poly = next;
                if poly.is_empty() {
                    break;
                }
            }
            if poly.is_empty() {
                continue;
            }
            let vs = poly.iter().map(|&(x, y)| v(x, y));
            let vmin = vs.clone().fold(f64::INFINITY, f64::min);
            let vmax = vs.fold(f64::NEG_INFINITY, f64::max);
            // A pixel on the rounding edge of a boundary may land one cell over: widen.
            for j in vmin.floor() as i64 - 1..=vmax.floor() as i64 + 1 {
                let ranks = self.rank_cell((i, j));
                let n = ranks.order.len() as f64;
                for (r, &(_, key)) in ranks.order.iter().enumerate() {
                    let (x, y) = Self::unkey(key);
                    let row = y - y0;
                    if row < 0 || row >= rows as i64 || x < 0 || x >= width as i64 {
                        continue;
                    }
                    let t = (r as f64 + ranks.stagger) / n;
                    out[row as usize * width + x as usize] =
                        ((t * 65536.0) as u32).min(65535) as u16;
                }
            }
        }
    }

    /// The measured geometry of a 16-bit threshold tile: the number of distinct thresholds.
    pub fn distinct_levels(tile: &[u16]) -> usize {
        let mut v = tile.to_vec();
        v.sort_unstable();
        v.dedup();
        v.len()
    }

    /// The repeat of the screen on the pixel grid, when it has a short one: the smallest
    /// `(w, h)`, both at most `limit`, such that shifting by `w` pixels across or `h` down
    /// maps cells onto cells with the same stagger. `None` for irrational screens.
    pub fn supercell(&self, limit: usize) -> Option<(usize, usize)> {
        // A shift of w pixels along x moves (u, v) by (w cos θ, −w sin θ)/p cells: the
        // screen repeats when both are whole multiples of 16 (the stagger period).
        let whole = |d: f64| {
            let q = d / 16.0;
            (q - q.round()).abs() < 1e-9
        };
        let w = (1..=limit).find(|&w| {
            let w = w as f64;
            whole(w * self.cos / self.period) && whole(-w * self.sin / self.period)
        })?;
        let h = (1..=limit).find(|&h| {
            let h = h as f64;
            // Moving down by h: py decreases by h.
            whole(-h * self.sin / self.period) && whole(-h * self.cos / self.period)
        })?;
        Some((w, h))
    }
}

/// Screen geometry measured from a halftone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measured {
    /// Period of the strongest periodic component, in pixels (dpi / period = lpi).
    pub period: f64,
    /// Its direction in degrees counter-clockwise from the x axis (y up), modulo 90.
    pub angle: f64,
}

/// In-place radix-2 FFT of `re`/`im` (length a power of two).
fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = -2.0 * PI / len as f64;
        for start in (0..n).step_by(len) {
            for k in 0..len / 2 {
                let (wr, wi) = (fm::cos(ang * k as f64), fm::sin(ang * k as f64));
                let (a, b) = (start + k, start + k + len / 2);
                let (xr, xi) = (re[b] * wr - im[b] * wi, re[b] * wi + im[b] * wr);
                re[b] = re[a] - xr;
                im[b] = im[a] - xi;
                re[a] += xr;
                im[a] += xi;
            }
        }
        len <<= 1;
    }
}

/// Measures the frequency and angle of a screen from a flat patch of it (`levels`: one
/// sample a pixel, row-major, any two values): the peak of the Hann-windowed 2-D spectrum,
/// found on the FFT grid and then refined off the grid by evaluating the Fourier sum
/// directly (hill-climbing with halving steps down to 10⁻⁴ of a bin). Uses the largest
/// power-of-two square in the top-left corner.
pub fn measure(levels: &[u8], width: usize, height: usize) -> Measured {
    let mut n = 1;
    while n * 2 <= width.min(height) {
        n *= 2;
    }
    assert!(n >= 16, "measure: need at least 16x16 samples");
    let hann: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * fm::cos(2.0 * PI * (i as f64 + 0.5) / n as f64))
        .collect();
    let mean = (0..n)
        .flat_map(|y| (0..n).map(move |x| (x, y)))
        .map(|(x, y)| levels[y * width + x] as f64)
        .sum::<f64>()
        / (n * n) as f64;
    let f: Vec<f64> = (0..n * n)
        .map(|i| {
            let (x, y) = (i % n, i / n);
            (levels[y * width + x] as f64 - mean) * hann[x] * hann[y]
        })
        .collect();
    // Coarse: full FFT.
    let mut re = f.clone();
    let mut im = vec![0.0; n * n];
    for r in 0..n {
        fft(&mut re[r * n..(r + 1) * n], &mut im[r * n..(r + 1) * n]);
    }
    let (mut cr, mut ci) = (vec![0.0; n], vec![0.0; n]);
    for c in 0..n {
        for r in 0..n {
            cr[r] = re[r * n + c];
            ci[r] = im[r * n + c];
        }
        fft(&mut cr, &mut ci);
        for r in 0..n {
            re[r * n + c] = cr[r];
            im[r * n + c] = ci[r];
        }
    }
    let signed = |k: usize| {
        if k >= n / 2 {
            k as f64 - n as f64
        } else {
            k as f64
        }
    };
    let mut best = (0.0, 0.0, -1.0);
    for ky in 0..n {
        for kx in 0..n {
            let (fx, fy) = (signed(kx), signed(ky));
            if fx * fx + fy * fy < 9.0 {
                continue;
            }
            let p = re[ky * n + kx].powi(2) + im[ky * n + kx].powi(2);
            if p > best.2 {
                best = (fx, fy, p);
            }
        }
    }
    // Fine: direct Fourier sums at off-grid frequencies, 3×3 around the best, step halving.
    let power = |fx: &[f64; 3], fy: &[f64; 3]| -> [[f64; 3]; 3] {
        // Row sums for each fx, then the column sum for each fy.
        let mut rows = vec![[(0.0f64, 0.0f64); 3]; n];
        for (a, &kx) in fx.iter().enumerate() {
            let w = -2.0 * PI * kx / n as f64;
            let tw: Vec<(f64, f64)> = (0..n)
                .map(|x| (fm::cos(w * x as f64), fm::sin(w * x as f64)))
                .collect();
            for (y, r) in rows.iter_mut().enumerate() {
                let (mut sr, mut si) = (0.0, 0.0);
                for (v, t) in f[y * n..(y + 1) * n].iter().zip(&tw) {
                    sr += v * t.0;
                    si += v * t.1;
                }
                r[a] = (sr, si);
            }
        }
        let mut out = [[0.0; 3]; 3];
        for (b, &ky) in fy.iter().enumerate() {
            let w = -2.0 * PI * ky / n as f64;
            for a in 0..3 {
                let (mut sr, mut si) = (0.0, 0.0);
                for (y, r) in rows.iter().enumerate() {
                    let (c, s) = (fm::cos(w * y as f64), fm::sin(w * y as f64));
                    sr += r[a].0 * c - r[a].1 * s;
                    si += r[a].0 * s + r[a].1 * c;
                }
                out[b][a] = sr * sr + si * si;
            }
        }
        out
    };
    let (mut kx, mut ky) = (best.0, best.1);
    let mut step = 0.5;
    while step > 1e-4 {
        let p = power(&[kx - step, kx, kx + step], &[ky - step, ky, ky + step]);
        let mut arg = (1, 1);
        for (b, row) in p.iter().enumerate() {
            for (a, &v) in row.iter().enumerate() {
                if v > p[arg.0][arg.1] {
                    arg = (b, a);
                }
            }
        }
        if arg == (1, 1) {
            step *= 0.5;
        } else {
            kx += (arg.1 as f64 - 1.0) * step;
            ky += (arg.0 as f64 - 1.0) * step;
        }
    }
    let radius = (kx * kx + ky * ky).sqrt();
    // Image rows go down; the screen's angle is measured with y up.
    let angle = fm::atan2(-ky, kx).to_degrees().rem_euclid(90.0) + 0.0;
    Measured {
        period: n as f64 / radius,
        angle,
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn band_fill_equals_row_lookup() {
        let mut screens = vec![
            (600.0, 106.0, 15.0, Spot::Round),
            (300.0, 150.0, 45.0, Spot::Round),
            (300.0, 150.0, 0.0, Spot::SimpleDot),
            (300.0, 60.0, 30.0, Spot::Ellipse),
            (600.0, 75.0, 75.0, Spot::Round),
            (600.0, 60.0, -15.0, Spot::Square),
            (203.0, 45.5, 180.0, Spot::Cross),
            (2400.0, 60.0, 45.0, Spot::Round),
        ];
        screens.extend(Spot::ALL.map(|s| (600.0, 133.0, 22.5, s)));
        for (dpi, lpi, angle, spot) in screens.into_iter().chain([
            (600.0, 106.0, 15.0, Spot::Round),
            (600.0, 106.0, 45.0, Spot::Ellipse),
            (300.0, 60.0, 0.0, Spot::Round),
            (600.0, 133.0, 37.5, Spot::Diamond),
            (600.0, 85.0, 90.0, Spot::Line),
            (1200.0, 150.0, -22.5, Spot::SimpleDot),
        ]) {
            let s = Screen::new(ScreenSpec {
                dpi,
                lpi,
                angle,
                spot,
            })
            .unwrap();
            let (w, rows) = (97, 23);
            for y0 in [0i64, 5, 1000] {
                let mut band = vec![0u16; w * rows];
                s.threshold_band(y0, rows, w, &mut band);
                let mut cache = CellCache::new();
                let mut row = vec![0u16; w];
                for r in 0..rows {
                    s.threshold_row(y0 + r as i64, 0, &mut row, &mut cache);
                    assert_eq!(
                        &band[r * w..(r + 1) * w],
                        &row[..],
                        "{lpi} lpi {angle}° row {}",
                        y0 + r as i64
                    );
                }
            }
        }
    }

    #[test]
    fn fast_floor_and_round_match_std() {
        let mut vals = vec![0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 1e15 + 0.5, -7.0];
        let mut x = 0.123_456_789f64;
        for _ in 0..10_000 {
            x = (x * 9301.0 + 0.4927).fract();
            vals.push((x - 0.5) * 1e6);
            vals.push((x - 0.5) * 3.0);
        }
        for k in -40..=40 {
            vals.push(k as f64 * 0.25);
            vals.push(k as f64 * 0.25 + 1e-9);
            vals.push(k as f64 * 0.25 - 1e-9);
            vals.push(k as f64 * 1e6 + 0.5);
            vals.push(-(k as f64) * 1e6 - 0.5);
        }
        for v in vals {
            assert_eq!(floor(v), v.floor(), "floor {v}");
            assert_eq!(round(v), v.round(), "round {v}");
            if v.abs() < 1e15 {
                assert_eq!(floor_rne(v), v.floor(), "floor_rne {v}");
                assert_eq!(round_rne(v), v.round(), "round_rne {v}");
                if v.abs() < 2e9 {
                    assert_eq!(low_i32(v.floor()) as f64, v.floor(), "low_i32 {v}");
                }
            }
        }
    }
    use super::*;

    #[test]
    fn bayer16_is_a_permutation() {
        let mut seen = [false; 256];
        for i in 0..16 {
            for j in 0..16 {
                let b = bayer16(i, j) as usize;
                assert!(!seen[b]);
                seen[b] = true;
            }
        }
        // Dispersed: the first four are one to each quadrant-of-2×2 … of the 16×16 tile.
        let first: Vec<(usize, usize)> = (0..16)
            .flat_map(|i| (0..16).map(move |j| (i, j)))
            .filter(|&(i, j)| bayer16(i, j) < 4)
            .collect();
        assert_eq!(first.len(), 4);
        for &(i, j) in &first {
            for &(k, l) in &first {
                if (i, j) != (k, l) {
                    assert!(i.abs_diff(k) >= 8 || j.abs_diff(l) >= 8, "{first:?}");
                }
            }
        }
    }

    #[test]
    fn names_parse_every_way() {
        for s in Spot::ALL {
            assert_eq!(Spot::from_name(s.name()).unwrap(), s);
            assert_eq!(Spot::from_name(&s.name().to_uppercase()).unwrap(), s);
        }
        assert_eq!(
            Spot::from_name("inverted-simple-dot").unwrap(),
            Spot::InvertedSimpleDot
        );
        let e = Spot::from_name("roundish").unwrap_err().to_string();
        assert!(e.contains("SimpleDot") && e.contains("Diamond"), "{e}");
    }

    #[test]
    fn spot_values_stay_in_range_and_round_is_continuous() {
        for s in Spot::ALL {
            for i in 0..=40 {
                for j in 0..=40 {
                    let (x, y) = (i as f64 / 20.0 - 1.0, j as f64 / 20.0 - 1.0);
                    let v = s.value(x, y);
                    assert!((-1.0..=1.0).contains(&v), "{s:?} {x} {y} {v}");
                }
            }
        }
        // Round (PDF): a growing disc inside the diamond |x|+|y| ≤ 1, a shrinking hole
        // outside it. The value jumps at the diamond's edge, but every point inside ranks
        // above every point outside (inside ≥ 0 > outside), and the corners meet.
        let inside = Spot::Round.value(0.5, 0.5 - 1e-12);
        let outside = Spot::Round.value(0.5, 0.5 + 1e-12);
        assert!(inside >= 0.0 && outside < 0.0, "{inside} {outside}");
        let (a, b) = (
            Spot::Round.value(1.0 - 1e-12, 0.0),
            Spot::Round.value(1.0, 1e-12),
        );
        assert!((a - b).abs() < 1e-9, "{a} {b}");
    }

    #[test]
    fn every_cell_ranks_its_pixels_once() {
        let s = Screen::new(ScreenSpec {
            dpi: 600.0,
            lpi: 106.0,
            angle: 15.0,
            spot: Spot::Round,
        })
        .unwrap();
        let mut cache = CellCache::new();
        // Collect (cell, threshold) over a region; within a cell, thresholds are distinct
        // and each rank 0..n−1 appears once for cells wholly inside.
        let mut by_cell: std::collections::HashMap<(i64, i64), Vec<f64>> =
            std::collections::HashMap::new();
        for y in 0..80 {
            for x in 0..80 {
                let (c, _) = s.locate(x, y);
                by_cell
                    .entry(c)
                    .or_default()
                    .push(s.threshold(x, y, &mut cache));
            }
        }
        let mut whole = 0;
        for (c, mut ts) in by_cell {
            let n = s.rank_cell(c).order.len();
            ts.sort_by(f64::total_cmp);
            if ts.len() == n {
                whole += 1;
                let d = ts[0] * n as f64;
                for (r, t) in ts.iter().enumerate() {
                    assert!((t * n as f64 - r as f64 - d).abs() < 1e-9);
                }
            }
        }
        assert!(whole > 100);
    }
}
