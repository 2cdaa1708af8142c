//! Placeholder: palette DBS (replaced by the pdbs branch).
use crate::error::Result;
/// Options.
#[derive(Clone, Debug, Default)]
pub struct PaletteDbsOptions {
    /// Pixels a degree.
    pub ppd: f64,
    /// Passes.
    pub passes: u32,
    /// Swaps.
    pub swaps: bool,
}
/// Refines indices.
pub fn refine(
    _target: &[[f32; 3]],
    _w: usize,
    _h: usize,
    _inks: &[[f32; 3]],
    _indices: &mut [u8],
    _opts: &PaletteDbsOptions,
) -> Result<u32> {
    Ok(0)
}
