//! Placeholder: ordered palette dithering (replaced by the pal branch).
/// Indices.
pub fn ordered_indices(
    _target: &[[f32; 3]],
    w: usize,
    h: usize,
    _inks: &[[f32; 3]],
    _mask: &crate::mask::Mask,
) -> Vec<u8> {
    vec![0; w * h]
}
