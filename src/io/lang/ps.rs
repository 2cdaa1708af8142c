//! PostScript level 2: one page an image, the page the image's physical size (or
//! `--page`, centred), the samples inline through `/ASCII85Decode` and `/RunLengthDecode`
//! filters (PLRM 2nd ed. §3.13), so the file is 7-bit text that any spooler passes and
//! rows stream through with a few bytes of state. DSC comments (`%%BoundingBox`,
//! `%%Page`, `%%PageBoundingBox`) let viewers and print managers find the pages.

use std::io::Write;

use super::{fail, find, number, numbers, space, value, DecodeResult, ImageHead};
use super::{Chunky, Language, PrintOptions};
use crate::io::sink::{Band, PageEncoder, PageHeader};
use crate::io::{EncodeError, EncodeResult};
use crate::raster::Image;

/// Streaming PostScript writer.
pub struct PsEncoder {
    opts: PrintOptions,
    pages: usize,
    /// The largest page so far, in whole points, for the trailer's `%%BoundingBox`.
    bbox: (u64, u64),
    page: Option<(PageHeader, Chunky, Ascii85, usize)>,
}

impl PsEncoder {
    /// A PostScript writer.
    pub fn new(opts: PrintOptions) -> PsEncoder {
        PsEncoder {
            opts,
            pages: 0,
            bbox: (0, 0),
            page: None,
        }
    }
}

impl PageEncoder for PsEncoder {
    fn begin_page(&mut self, page: &PageHeader, out: &mut dyn Write) -> EncodeResult {
        if let Some(msg) = super::check(Language::Ps, page, &self.opts) {
            return Err(EncodeError::Other(msg));
        }
        if self.pages == 0 {
            out.write_all(
                b"%!PS-Adobe-3.0\n%%Creator: halftone\n%%LanguageLevel: 2\n%%BoundingBox: (atend)\n%%Pages: (atend)\n%%EndComments\n",
            )?;
        }
        self.pages += 1;
        let dpi = super::page_dpi(page);
        let (x, y, pw, ph) = super::placement(page, &self.opts, dpi);
        let (w, h) = super::image_points(page, dpi);
        let (bw, bh) = (pw.ceil() as u64, ph.ceil() as u64);
        self.bbox = (self.bbox.0.max(bw), self.bbox.1.max(bh));
        let n = self.pages;
        let (space, decode) = if let Some(p) = &page.palette {
            let hex: String = p.iter().flatten().map(|b| format!("{b:02X}")).collect();
            (
                format!("[/Indexed /DeviceRGB {} <{hex}>]", p.len() - 1),
                format!("[0 {}]", (1u32 << page.bits) - 1),
            )
        } else {
            let d = super::num(super::decode_max(page.bits, page.levels));
            if page.channels == 3 {
                ("/DeviceRGB".to_string(), format!("[0 {d} 0 {d} 0 {d}]"))
            } else {
                ("/DeviceGray".to_string(), format!("[0 {d}]"))
            }
        };
        let head = format!(
            "%%Page: {n} {n}\n%%PageBoundingBox: 0 0 {bw} {bh}\n%%BeginPageSetup\n<< /PageSize [{pw} {ph}] >> setpagedevice\n%%EndPageSetup\nsave\n{space} setcolorspace\n{x} {y} translate {w} {h} scale\n<< /ImageType 1 /Width {iw} /Height {ih} /BitsPerComponent {bits} /Decode {decode} /ImageMatrix [{iw} 0 0 -{ih} 0 {ih}] /DataSource currentfile /ASCII85Decode filter /RunLengthDecode filter >> image\n",
            pw = super::num(pw),
            ph = super::num(ph),
            x = super::num(x),
            y = super::num(y),
            w = super::num(w),
            h = super::num(h),
            iw = page.width,
            ih = page.height,
            bits = page.bits,
        );
        out.write_all(head.as_bytes())?;
        self.page = Some((page.clone(), Chunky::new(page), Ascii85::default(), 0));
        Ok(())
    }

    fn write_rows(&mut self, band: &Band<'_>, out: &mut dyn Write) -> EncodeResult {
        let (page, chunky, a85, rows) = crate::io::sink::page_for_rows(&mut self.page)?;
        let mut rl = Vec::new();
        for r in 0..band.rows {
            rl.clear();
            run_length(chunky.build(band.planes, page.stride, r), &mut rl);
            a85.write(&rl, out)?;
        }
        *rows += band.rows;
        Ok(())
    }

    fn end_page(&mut self, out: &mut dyn Write) -> EncodeResult {
        let (_, _, mut a85, _) =
            crate::io::sink::take_complete_page(&mut self.page, |(page, _, _, rows)| {
                (*rows, page.height)
            })?;
        // RunLengthDecode's end of data, then ASCII85's.
        a85.write(&[128], out)?;
        a85.finish(out)?;
        out.write_all(b"\nrestore\nshowpage\n")?;
        Ok(())
    }

    fn finish(&mut self, out: &mut dyn Write) -> EncodeResult {
        if self.pages == 0 {
            return Err(EncodeError::Other("no pages to write".into()));
        }
        write!(
            out,
            "%%Trailer\n%%BoundingBox: 0 0 {} {}\n%%Pages: {}\n%%EOF\n",
            self.bbox.0, self.bbox.1, self.pages
        )?;
        out.flush()?;
        Ok(())
    }
}

/// PostScript's RunLengthDecode coding (PLRM §3.13.3), the same as PackBits: a length byte
/// n of 0..127 copies the next n + 1 bytes, 129..255 repeats the next byte 257 − n times.
/// The end-of-data byte (128) is the caller's.
pub fn run_length(data: &[u8], out: &mut Vec<u8>) {
    let mut i = 0;
    while i < data.len() {
        // A run of at least 2 equal bytes becomes a repeat.
        let mut run = 1;
        while i + run < data.len() && run < 128 && data[i + run] == data[i] {
            run += 1;
        }
        if run >= 2 {
            out.push((257 - run) as u8);
            out.push(data[i]);
            i += run;
            continue;
        }
        // A literal up to the next run of 3 (a run of 2 inside a literal costs no more).
        let start = i;
        while i < data.len() && i - start < 128 {
            if i + 2 < data.len() && data[i] == data[i + 1] && data[i] == data[i + 2] {
                break;
            }
            i += 1;
        }
        out.push((i - start - 1) as u8);
        out.extend_from_slice(&data[start..i]);
    }
}

/// ASCII85 (PLRM §3.13.3): four bytes as five characters `!`..`u`, `z` for four zeros,
/// lines of at most 75 characters, `~>` at the end.
#[derive(Default)]
pub struct Ascii85 {
    pending: [u8; 4],
    n: usize,
    column: usize,
    line: Vec<u8>,
}

impl Ascii85 {
    /// Encodes `data`.
    pub fn write(&mut self, data: &[u8], out: &mut dyn Write) -> std::io::Result<()> {
        for &b in data {
            self.pending[self.n] = b;
            self.n += 1;
            if self.n == 4 {
                self.group(4);
                self.n = 0;
            }
        }
        out.write_all(&self.line)?;
        self.line.clear();
        Ok(())
    }

    fn group(&mut self, n: usize) {
        let mut buf = [0u8; 4];
        buf[..n].copy_from_slice(&self.pending[..n]);
        let v = u32::from_be_bytes(buf);
        if n == 4 && v == 0 {
            self.emit(b"z");
            return;
        }
        let mut c = [0u8; 5];
        let mut v = v;
        for d in c.iter_mut().rev() {
            *d = b'!' + (v % 85) as u8;
            v /= 85;
        }
        self.emit_owned(&c[..n + 1]);
    }

    fn emit(&mut self, s: &[u8]) {
        self.emit_owned(s)
    }

    fn emit_owned(&mut self, s: &[u8]) {
        for &ch in s {
            if self.column == 75 {
                self.line.push(b'\n');
                self.column = 0;
            }
            self.line.push(ch);
            self.column += 1;
        }
    }

    /// Encodes the last partial group and the end marker `~>`.
    pub fn finish(&mut self, out: &mut dyn Write) -> std::io::Result<()> {
        if self.n > 0 {
            self.group(self.n);
            self.n = 0;
        }
        self.line.extend_from_slice(b"~>");
        out.write_all(&self.line)?;
        self.line.clear();
        self.column = 0;
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------
// Decoding

/// Decodes the pages of a PostScript file that halftone wrote: each `image` with its
/// samples inline as ASCII85 of run-length data, as 8-bit codes.
pub fn decode(data: &[u8]) -> DecodeResult<Vec<Image>> {
    const TAIL: &[u8] =
        b"/DataSource currentfile /ASCII85Decode filter /RunLengthDecode filter >> image\n";
    let mut pages = Vec::new();
    let mut at = 0;
    while let Some(p) = find(data, TAIL, at) {
        let Some(open) = data[..p].windows(2).rposition(|w| w == b"<<") else {
            return fail("an image without its dictionary");
        };
        let dict = std::str::from_utf8(&data[open..p]).unwrap_or("");
        let line_start = data[..open]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |i| i + 1);
        // The colour space is set two lines before the image: `… setcolorspace`.
        let before = std::str::from_utf8(&data[..line_start]).unwrap_or("");
        let cs_line = before
            .lines()
            .rev()
            .find(|l| l.ends_with("setcolorspace"))
            .unwrap_or("");
        let head = ImageHead {
            width: number(dict, "/Width")?,
            height: number(dict, "/Height")?,
            bits: number(dict, "/BitsPerComponent")? as u32,
            space: space(cs_line.trim(), cs_line)?,
            decode: value(dict, "/Decode").map(numbers).unwrap_or_default(),
        };
        head.check()?;
        let start = p + TAIL.len();
        let (packed, end) = decode_ascii85(data, start)?;
        let expected = head.stride() * head.height;
        let raw = decode_run_length(&packed, expected)?;
        pages.push(head.image(&raw)?);
        at = end;
    }
    if pages.is_empty() {
        return fail("no image");
    }
    Ok(pages)
}

/// Decodes ASCII85 text from `start` to its `~>`; returns the bytes and the offset after it.
pub fn decode_ascii85(data: &[u8], start: usize) -> DecodeResult<(Vec<u8>, usize)> {
    let mut out = Vec::new();
    let mut group = [0u8; 5];
    let mut n = 0;
    let mut i = start;
    loop {
        let Some(&c) = data.get(i) else {
            return fail("ASCII85 data without its end (~>)");
        };
        i += 1;
        match c {
            b'~' => {
                if data.get(i) != Some(&b'>') {
                    return fail(format!("ASCII85: '~' without '>' at byte {}", i - 1));
                }
                i += 1;
                break;
            }
            b'z' if n == 0 => out.extend_from_slice(&[0; 4]),
            b'!'..=b'u' => {
                group[n] = c - b'!';
                n += 1;
                if n == 5 {
                    out.extend_from_slice(&a85_group(&group, i - 1)?);
                    n = 0;
                }
            }
            c if c.is_ascii_whitespace() => {}
            c => return fail(format!("ASCII85: byte {c:#04x} at {}", i - 1)),
        }
    }
    match n {
        0 => {}
        1 => return fail("ASCII85: a final group of one character"),
        _ => {
            // A final group of n characters stands for n − 1 bytes, padded with 'u'.
            group[n..].fill(b'u' - b'!');
            let bytes = a85_group(&group, i)?;
            out.extend_from_slice(&bytes[..n - 1]);
        }
    }
    Ok((out, i))
}

fn a85_group(g: &[u8; 5], at: usize) -> DecodeResult<[u8; 4]> {
    let v = g.iter().fold(0u64, |v, &d| v * 85 + d as u64);
    match u32::try_from(v) {
        Ok(v) => Ok(v.to_be_bytes()),
        Err(_) => fail(format!("ASCII85: a group over 2^32 before byte {at}")),
    }
}

/// Decodes RunLengthDecode data (PLRM §3.13.3) up to its end-of-data byte (128) or
/// `limit` bytes.
pub fn decode_run_length(data: &[u8], limit: usize) -> DecodeResult<Vec<u8>> {
    let mut out = Vec::with_capacity(limit);
    let mut i = 0;
    while out.len() < limit {
        let Some(&n) = data.get(i) else {
            return fail("run-length data without its end");
        };
        match n {
            128 => break,
            0..=127 => {
                let k = n as usize + 1;
                let Some(s) = data.get(i + 1..i + 1 + k) else {
                    return fail("run-length data cut short");
                };
                out.extend_from_slice(s);
                i += 1 + k;
            }
            _ => {
                let Some(&b) = data.get(i + 1) else {
                    return fail("run-length data cut short");
                };
                out.extend(std::iter::repeat_n(b, 257 - n as usize));
                i += 2;
            }
        }
    }
    out.truncate(limit);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unrun(data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        let mut i = 0;
        while i < data.len() {
            let n = data[i] as usize;
            if n < 128 {
                out.extend_from_slice(&data[i + 1..i + 2 + n]);
                i += n + 2;
            } else {
                out.extend(std::iter::repeat_n(data[i + 1], 257 - n));
                i += 2;
            }
        }
        out
    }

    #[test]
    fn run_length_round_trips() {
        let cases: Vec<Vec<u8>> = vec![
            vec![],
            vec![7],
            vec![1, 2, 3],
            vec![0; 300],
            (0..=255).collect(),
            [vec![5; 3], vec![1, 2], vec![9; 130], vec![1, 1, 2]].concat(),
        ];
        for c in cases {
            let mut e = Vec::new();
            run_length(&c, &mut e);
            assert_eq!(unrun(&e), c);
        }
    }

    #[test]
    fn ascii85_known_text() {
        // The PLRM's rule: 4 zero bytes are `z`; a partial group of n bytes gives n + 1 chars.
        let mut a = Ascii85::default();
        let mut out = Vec::new();
        a.write(b"Man \0\0\0\0is", &mut out).unwrap();
        a.finish(&mut out).unwrap();
        assert_eq!(out, b"9jqo^zBla~>");
    }
}
