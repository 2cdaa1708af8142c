//! `--max-memory`: the memory budget of the streaming pipeline.

use clap::Args;

use halftone::pipeline::MaxMemory;

/// Memory options shared by `convert` and `batch`.
#[derive(Args, Debug, Clone)]
pub struct MemoryArgs {
    /// Memory for image data: a size such as 64M or 2G, or auto. Images that do not fit are
    /// streamed in bands of rows (PNM, PNG and TIFF-strip input; threshold, ordered, pattern and error
    /// diffusion except Riemersma and palettes); work that needs the whole image and does
    /// not fit is refused before decoding [default: auto: whole images up to a quarter of
    /// the free memory (at most 1 GiB), streaming beyond].
    #[arg(long, value_name = "SIZE", value_parser = parse_max_memory)]
    pub max_memory: Option<MaxMemory>,
}

impl MemoryArgs {
    /// The budget asked for.
    pub fn max_memory(&self) -> MaxMemory {
        self.max_memory.unwrap_or_default()
    }
}

fn parse_max_memory(s: &str) -> Result<MaxMemory, String> {
    MaxMemory::parse(s).map_err(|e| super::flags_for_options(&e.to_string()))
}
