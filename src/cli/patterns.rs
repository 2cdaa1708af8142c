//! `halftone patterns`: a mask's pattern table, every level's cell.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Args, ValueEnum};

use halftone::method::pattern::pattern_table;
use halftone::{io, Mask};

pub const EXAMPLES: &str = "Examples:
  halftone patterns                          # the lecture's 3x3 mask, 10 patterns
  halftone patterns --mask seed-2x2 --levels 4   # the lecture's 13-level table
  halftone patterns --mask bayer-4 --format json
  halftone patterns --mask seed-3x3 -o sheet.png
  halftone patterns --screen --dpi 600 --lpi 106 --angle 15 --spot round
  halftone patterns --screen --dpi 600 --lpi 106 --angle 45 -o screen.pgm";

/// Table formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TableFormat {
    /// Cells side by side as numbers (device level of each pixel).
    Text,
    /// One object per level.
    Json,
}

/// `halftone patterns` arguments.
#[derive(Args, Debug)]
pub struct PatternsArgs {
    /// Mask: a built-in name or a mask file of position numbers.
    #[arg(long, default_value = "seed-3x3")]
    pub mask: String,

    /// Device levels a pixel (2 = bilevel).
    #[arg(long, short = 'l', default_value_t = 2)]
    pub levels: u16,

    /// Output form on stdout.
    #[arg(long, value_enum, default_value = "text")]
    pub format: TableFormat,

    /// Write an image sheet (PNG) of enlarged, labelled cells instead (with --screen: the
    /// threshold array, as a 16-bit PGM or, for any other extension, a mask file).
    #[arg(long, short = 'o')]
    pub output: Option<PathBuf>,

    #[command(flatten)]
    pub screen: super::patterns_screen::PatternScreenArgs,
}

pub fn run(a: PatternsArgs) -> anyhow::Result<ExitCode> {
    if a.screen.screen {
        return super::patterns_screen::patterns(&a.screen, a.output.as_deref());
    }
    halftone::method::threshold::check_levels(a.levels)?;
    let mask = Mask::load(&a.mask, true)?;
    check_table_size(&mask, a.levels)?;
    let table = pattern_table(&mask, a.levels);
    if let Some(path) = &a.output {
        let sheet = sheet(&mask, &table, a.levels);
        let mut buf = Vec::new();
        image::GrayImage::from_raw(sheet.0, sheet.1, sheet.2)
            .expect("sheet size")
            .write_to(&mut std::io::Cursor::new(&mut buf), image::ImageFormat::Png)
            .with_context(|| format!("{}: cannot encode PNG", path.display()))?;
        io::write_atomic(path, |w| w.write_all(&buf))?;
        return Ok(ExitCode::SUCCESS);
    }
    let out = match a.format {
        TableFormat::Text => text(&mask, &table, a.levels),
        TableFormat::Json => json(&mask, &table, a.levels),
    };
    super::stdio::check_stdout()?;
    let mut stdout = std::io::stdout().lock();
    stdout.write_all(out.as_bytes())?;
    stdout.flush()?;
    Ok(ExitCode::SUCCESS)
}

/// The most cells a pattern table may hold (patterns × cells a pattern): 2^20, a 32×32
/// mask at two levels. blue-noise-128's table would be 16385 patterns of 16384 cells,
/// 268 million numbers (537 MB of text, or a 977 MB sheet): a table that size is not
/// something to print.
const MAX_TABLE_CELLS: u64 = 1 << 20;

/// Refuses a table over [`MAX_TABLE_CELLS`] before it is built.
fn check_table_size(mask: &Mask, levels: u16) -> anyhow::Result<()> {
    let n = mask.len() as u64;
    let patterns = n.saturating_mul(levels as u64 - 1).saturating_add(1);
    let cells = patterns.saturating_mul(n);
    if cells > MAX_TABLE_CELLS {
        anyhow::bail!(
            "{}: a {}x{} mask at {levels} levels has {patterns} patterns of {n} cells \
             ({cells} numbers), over the {MAX_TABLE_CELLS} a pattern table may hold; \
             use `halftone masks show` for large masks",
            mask.name,
            mask.width,
            mask.height
        );
    }
    Ok(())
}

fn text(mask: &Mask, table: &[Vec<u8>], levels: u16) -> String {
    let mut s = format!(
        "{}: {}x{} mask, {} level(s) a pixel, {} patterns; numbers are device levels \
         (0 = ink, {} = lit)\n\n",
        mask.name,
        mask.width,
        mask.height,
        levels,
        table.len(),
        levels - 1
    );
    let digit_w = (levels - 1).to_string().len();
    let cell_w = (mask.width * (digit_w + 1) - 1).max("level 99".len());
    let per_line = (78 / (cell_w + 3)).max(1);
    for group in table.chunks(per_line).enumerate() {
        let (g, cells) = group;
        let heads: Vec<String> = (0..cells.len())
            .map(|i| format!("{:<cell_w$}", format!("level {}", g * per_line + i)))
            .collect();
        s.push_str(heads.join("   ").trim_end());
        s.push('\n');
        for y in 0..mask.height {
            let rows: Vec<String> = cells
                .iter()
                .map(|c| {
                    let r: Vec<String> = c[y * mask.width..(y + 1) * mask.width]
                        .iter()
                        .map(|v| format!("{v:>digit_w$}"))
                        .collect();
                    format!("{:<cell_w$}", r.join(" "))
                })
                .collect();
            s.push_str(rows.join("   ").trim_end());
            s.push('\n');
        }
        s.push('\n');
    }
    s
}

fn json(mask: &Mask, table: &[Vec<u8>], levels: u16) -> String {
    let patterns: Vec<serde_json::Value> = table
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let rows: Vec<&[u8]> = c.chunks(mask.width).collect();
            serde_json::json!({ "level": k, "cell": rows })
        })
        .collect();
    let v = serde_json::json!({
        "mask": mask.name,
        "width": mask.width,
        "height": mask.height,
        "device_levels": levels,
        "numbers": mask.ranks.iter().map(|r| r + 1).collect::<Vec<_>>().chunks(mask.width).collect::<Vec<_>>(),
        "patterns": patterns,
    });
    let mut s = serde_json::to_string_pretty(&v).expect("json");
    s.push('\n');
    s
}

/// 3×5 digits, one row of three bits per line, for cell labels.
const DIGITS: [[u8; 5]; 10] = [
    [7, 5, 5, 5, 7],
    [2, 6, 2, 2, 7],
    [7, 1, 7, 4, 7],
    [7, 1, 7, 1, 7],
    [5, 5, 7, 1, 1],
    [7, 4, 7, 1, 7],
    [7, 4, 7, 5, 7],
    [7, 1, 1, 1, 1],
    [7, 5, 7, 5, 7],
    [7, 5, 7, 1, 7],
];

/// A sheet like the lecture's figures: each cell enlarged, pixels shown as their device
/// level's tone, a grid between pixels, the level number below. Returns (w, h, pixels).
fn sheet(mask: &Mask, table: &[Vec<u8>], levels: u16) -> (u32, u32, Vec<u8>) {
    let px = (96 / mask.width.max(mask.height)).clamp(4, 24);
    let (cw, ch) = (mask.width * px, mask.height * px);
    let label_h = 5 * 3 + 6;
    let pad = 12;
    let cols = table.len().min(8);
    let rows = table.len().div_ceil(cols);
    let (w, h) = (pad + cols * (cw + pad), pad + rows * (ch + label_h + pad));
    let mut img = vec![255u8; w * h];
    let shade: Vec<u8> = (0..levels)
        .map(|l| halftone::tone::linear_to_srgb8(l as f64 / (levels - 1) as f64))
        .collect();
    for (k, cell) in table.iter().enumerate() {
        let ox = pad + (k % cols) * (cw + pad);
        let oy = pad + (k / cols) * (ch + label_h + pad);
        for y in 0..ch {
            for x in 0..cw {
                let grid = x % px == 0 || y % px == 0 || x == cw - 1 || y == ch - 1;
                let v = cell[(y / px) * mask.width + x / px];
                img[(oy + y) * w + ox + x] = if grid { 128 } else { shade[v as usize] };
            }
        }
        // Label, 3× scaled digits, centred under the cell.
        let label = k.to_string();
        let lw = label.len() * 12 - 3;
        let lx = ox + cw.saturating_sub(lw) / 2;
        let ly = oy + ch + 4;
        for (i, d) in label.bytes().enumerate() {
            let glyph = DIGITS[(d - b'0') as usize];
            for (gy, bits) in glyph.iter().enumerate() {
                for gx in 0..3 {
                    if bits >> (2 - gx) & 1 == 1 {
                        for sy in 0..3 {
                            for sx in 0..3 {
                                let (x, y) = (lx + i * 12 + gx * 3 + sx, ly + gy * 3 + sy);
                                if x < w && y < h {
                                    img[y * w + x] = 0;
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    (w as u32, h as u32, img)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_table_of_lecture_mask() {
        let m = Mask::builtin("seed-3x3").unwrap();
        let t = text(&m, &pattern_table(&m, 2), 2);
        assert!(t.starts_with("seed-3x3: 3x3 mask, 2 level(s) a pixel, 10 patterns"));
        assert!(t.contains("level 9"));
    }

    #[test]
    fn sheet_has_every_cell() {
        let m = Mask::builtin("seed-2x2").unwrap();
        let (w, h, px) = sheet(&m, &pattern_table(&m, 4), 4);
        assert_eq!(px.len(), (w * h) as usize);
        assert!(px.contains(&0) && px.contains(&255));
    }
}
