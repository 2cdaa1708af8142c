//! Flags of the printer formats (PDF, PostScript, PCL, ESC/POS, ZPL) and of `--content`.

use std::path::Path;

use clap::{Args, ValueEnum};

use halftone::io::print::{PageSize, PrintOptions, ZplEncoding, MAX_BAND_ROWS, ZPL_MAX_LENGTH};
use halftone::io::Format;
use halftone::ContentKind;

/// What the picture is, for `--content`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ContentArg {
    /// Halftone everything with the method.
    Photo,
    /// Threshold everything: text, rules, barcodes and QR codes stay crisp.
    LineArt,
    /// Threshold the regions that are already near black and white, halftone the rest.
    Auto,
}

/// ZPL graphic field encodings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ZplEncodingArg {
    /// Hexadecimal with Zebra's ASCII compression (every ZPL printer).
    Hex,
    /// zlib + base64 with a CRC (`:Z64:`; smaller, firmware from about 2008 on).
    Z64,
}

/// Printer-format options shared by `convert` and `batch`.
#[derive(Args, Debug, Clone)]
pub struct PrintArgs {
    /// PDF, PostScript, PCL: the page to centre the image on (a4, letter, or WxH with in
    /// or mm, e.g. 4x6in); default: the image's own size at --dpi.
    #[arg(long, value_name = "SIZE", value_parser = parse_page)]
    pub page: Option<PageSize>,

    /// ESC/POS: rows per `GS v 0` raster band (at most 960; smaller for printers with
    /// small buffers).
    #[arg(long, default_value_t = MAX_BAND_ROWS, value_name = "N")]
    pub band_rows: usize,

    /// ESC/POS: feed and cut the paper after each image.
    #[arg(long)]
    pub cut: bool,

    /// ESC/POS: print head width in dots (384 for 58 mm and 576 for 80 mm paper at 203 dpi,
    /// 512 at 180 dpi); a wider image is refused.
    #[arg(long, value_name = "DOTS")]
    pub paper_width: Option<usize>,

    /// ZPL: graphic field encoding.
    #[arg(long, value_enum, default_value = "hex")]
    pub zpl_encoding: ZplEncodingArg,

    /// ZPL: the printer's longest label in dots; a longer one is refused.
    #[arg(long, default_value_t = ZPL_MAX_LENGTH, value_name = "DOTS")]
    pub max_length: usize,

    /// Photo: halftone everything; line-art: threshold everything; auto: threshold the
    /// near-black-and-white regions (text, barcodes) and halftone the rest.
    #[arg(long, value_enum, default_value = "photo")]
    pub content: ContentArg,
}

fn parse_page(s: &str) -> Result<PageSize, String> {
    s.parse().map_err(|e: String| super::flags_for_options(&e))
}

impl PrintArgs {
    /// The library's options.
    pub fn options(&self) -> PrintOptions {
        PrintOptions {
            page: self.page,
            band_rows: self.band_rows,
            cut: self.cut,
            paper_width: self.paper_width,
            zpl_encoding: match self.zpl_encoding {
                ZplEncodingArg::Hex => ZplEncoding::Hex,
                ZplEncodingArg::Z64 => ZplEncoding::Z64,
            },
            max_length: self.max_length,
        }
    }

    /// The library's name for `--content`.
    pub fn content(&self) -> ContentKind {
        match self.content {
            ContentArg::Photo => ContentKind::Photo,
            ContentArg::LineArt => ContentKind::LineArt,
            ContentArg::Auto => ContentKind::Auto,
        }
    }
}

/// The multi-page format of a batch writing into one file (`-o book.pdf`, or `-o -` with
/// a multi-page `--format`), `None` for a folder of outputs.
pub fn book_format(output: &Path, format: Option<Format>) -> Option<Format> {
    if output.as_os_str() == "-" {
        return format.filter(|f| f.is_multi_page());
    }
    if output.is_dir() {
        return None;
    }
    let by_name = Format::from_path(output).filter(|f| f.is_multi_page())?;
    Some(format.unwrap_or(by_name)).filter(|f| f.is_multi_page())
}
