//! Panel buffers read back by an independent decoder. `devices.rs` decodes every encoding
//! with Rust written in this test crate, through the library, at small sizes; here the
//! binary converts a sample picture at each panel's own size (`--device NAME`), and a
//! Python 3 script (standard library only: `zlib`, `struct`, `tomllib`) decodes every
//! buffer from the layout in docs/devices.md, reads the profile with its own TOML parser
//! (from `halftone devices show`), reads the PNG's palette indices by inflating its IDAT
//! and undoing the row filters itself, and checks that every buffer holds exactly the PNG's
//! indices, that the padding bits are zero, and that the PNG's palette is the profile's
//! measured (or nominal) colours. Nothing of our Rust code reads the bytes.

use std::path::Path;
use std::process::Command;

use halftone::panel::Device;

use crate::common::{halftone as bin, have_tool};

/// The decoder. Arguments: the profile (TOML), the PNG, then `format=path` for each buffer.
/// Prints one line a buffer, `FORMAT equal W H` or `FORMAT differ …`, and exits 1 on any
/// difference or malformed buffer.
const DECODER: &str = r##"
import re, struct, sys, tomllib, zlib

profile = tomllib.load(open(sys.argv[1], "rb"))
inks = profile["ink"]
codes = [i["code"] for i in inks]
names = [i["name"] for i in inks]

def hexcol(s):
    s = s.lstrip("#")
    return (int(s[0:2], 16), int(s[2:4], 16), int(s[4:6], 16))

def read_png(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "PNG signature"
    pos, idat, plte, ihdr = 8, b"", None, None
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + n]
        (crc,) = struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])
        assert zlib.crc32(kind + body) == crc, "CRC of " + kind.decode()
        pos += 12 + n
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"PLTE":
            plte = [tuple(body[i:i + 3]) for i in range(0, len(body), 3)]
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
    w, h, depth, ctype, _, _, interlace = ihdr
    assert ctype == 3 and interlace == 0, "indexed, not interlaced"
    raw = zlib.decompress(idat)
    stride = (w * depth + 7) // 8
    assert len(raw) == h * (stride + 1), "inflated size"
    prev, rows = bytearray(stride), []
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        if f == 2:
            line = bytearray((a + b) & 255 for a, b in zip(line, prev))
        elif f in (1, 3, 4):
            for i in range(stride):
                a = line[i - 1] if i else 0
                b = prev[i]
                c = prev[i - 1] if i else 0
                if f == 1:
                    line[i] = (line[i] + a) & 255
                elif f == 3:
                    line[i] = (line[i] + ((a + b) >> 1)) & 255
                else:
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pr = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                    line[i] = (line[i] + pr) & 255
        else:
            assert f == 0, "filter type %d" % f
        rows.append(bytes(line))
        prev = line
    table = unpack_table(depth, msb_first=True)
    idx = b"".join(b"".join(map(table.__getitem__, r))[:w] for r in rows)
    return w, h, idx, plte

def unpack_table(bits, msb_first):
    per = 8 // bits
    mask = (1 << bits) - 1
    out = []
    for b in range(256):
        vals = [(b >> (8 - bits * (k + 1))) & mask for k in range(per)]
        out.append(bytes(vals if msb_first else vals[::-1]))
    return out

# Code -> index; an unknown code becomes 255, which no index equals.
to_index = bytearray([255] * 256)
for i, c in enumerate(codes):
    to_index[c] = i
to_index = bytes(to_index)

def packed(data, w, h, bits, what):
    stride = (w * bits + 7) // 8
    assert len(data) == stride * h, "%s: %d bytes, want %d" % (what, len(data), stride * h)
    table = unpack_table(bits, msb_first=True)
    used = w * bits
    out = []
    for y in range(h):
        row = data[y * stride:(y + 1) * stride]
        if used % 8:
            assert row[-1] & (0xFF >> (used % 8)) == 0, "%s: padding bits of row %d" % (what, y)
        out.append(b"".join(map(table.__getitem__, row))[:w])
    return b"".join(out)

def decode_raw(data, w, h):
    bits = profile.get("bits") or next(b for b in (1, 2, 4, 8) if max(codes) < (1 << b))
    return packed(data, w, h, bits, "raw").translate(to_index)

def decode_h(data, w, h):
    text = data.decode("ascii")
    defs = dict(re.findall(r"^#define (\w+) (\d+)$", text, re.M))
    name = profile["name"].replace("-", "_")
    assert int(defs[name.upper() + "_WIDTH"]) == w and int(defs[name.upper() + "_HEIGHT"]) == h
    bits = int(defs[name.upper() + "_BITS"])
    m = re.search(r"const uint8_t (\w+)\[(\d+)\] = \{([^}]*)\};", text)
    assert m and m.group(1) == name, "array name"
    body = bytes(int(v, 16) for v in re.findall(r"0x([0-9a-fA-F]{2})", m.group(3)))
    assert len(body) == int(m.group(2)), "declared length"
    return packed(body, w, h, bits, "h").translate(to_index)

def decode_planes(data, w, h):
    black, white = names.index("black"), names.index("white")
    colour = [i for i in range(len(inks)) if i not in (black, white)]
    pol = profile.get("planes", {})
    pb, pcol = pol.get("black", 0), pol.get("colour", 1)
    stride = (w + 7) // 8
    n = stride * h
    assert len(data) == n * (1 + len(colour)), "planes size"
    kb = packed(data[:n], w, h, 1, "black plane")
    kc = packed(data[n:], w, h, 1, "colour plane") if colour else bytes(w * h)
    # Each byte is 0 or 1, so the sum has no carries: 2·black bit + colour bit.
    both = (int.from_bytes(kb, "big") * 2 + int.from_bytes(kc, "big")).to_bytes(w * h, "big")
    table = bytearray(256)
    for b in (0, 1):
        for c in (0, 1):
            is_black, is_colour = b == pb, bool(colour) and c == pcol
            table[2 * b + c] = 255 if (is_black and is_colour) else (
                black if is_black else (colour[0] if is_colour else white))
    return both.translate(bytes(table))

def decode_nibbles(data, w, h):
    stride = (w + 1) // 2
    assert len(data) == stride * h, "nibbles size"
    table = unpack_table(4, msb_first=False)
    out = []
    for y in range(h):
        row = data[y * stride:(y + 1) * stride]
        if w % 2:
            assert row[-1] >> 4 == 0, "padding nibble of row %d" % y
        out.append(b"".join(map(table.__getitem__, row))[:w])
    return b"".join(out).translate(to_index)

w, h, want, plte = read_png(sys.argv[2])
shown = []
for i in inks:
    if "measured" in i:
        shown.append(hexcol(i["measured"]))
    elif "measured_lab" in i:
        shown.append(None)  # converted by the library; not checked here
    else:
        shown.append(hexcol(i["nominal"]))
assert len(plte) == len(inks), "PLTE entries"
assert all(s is None or s == p for s, p in zip(shown, plte)), "PLTE %r, profile %r" % (plte, shown)
assert max(want) < len(inks), "PNG index out of range"
used = len(set(want))
print("png %d %d inks %d used %d plte-checked %d" % (w, h, len(inks), used, sum(s is not None for s in shown)))
bad = 0
for arg in sys.argv[3:]:
    fmt, path = arg.split("=", 1)
    data = open(path, "rb").read()
    got = {"raw": decode_raw, "h": decode_h, "planes": decode_planes, "nibbles": decode_nibbles}[fmt](data, w, h)
    if got == want:
        print("%s equal %d %d" % (fmt, w, h))
    else:
        diff = [k for k in range(w * h) if got[k] != want[k]]
        k = diff[0]
        print("%s differ at %d pixels, first %d,%d: %d for %d" % (fmt, len(diff), k % w, k // w, got[k], want[k]))
        bad += 1
sys.exit(1 if bad else 0)
"##;

/// [`check_device_with`] the picture fitted inside the panel (`--fit-mode inside`): sizes
/// of every parity, so the rows' padding is checked too.
fn check_device(name: &str) -> Option<(usize, usize)> {
    check_device_with(name, &["--fit-mode", "inside"])
}

/// Converts the sample picture for `device` (with `flags`) to a PNG and every other
/// encoding it offers, decodes them with [`DECODER`] and checks each one equals the PNG;
/// returns the PNG's size.
fn check_device_with(name: &str, flags: &[&str]) -> Option<(usize, usize)> {
    let check = format!("panel_decode {name}");
    if !have_tool("python3", "python3", &check) {
        return None;
    }
    let d = Device::builtin(name).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/raytrace.png");
    let profile = dir.path().join("profile.toml");
    let shown = bin().args(["devices", "show", name]).output().unwrap();
    assert!(shown.status.success());
    std::fs::write(&profile, &shown.stdout).unwrap();
    let convert = |format: &str| {
        let out = dir.path().join(format!("out.{format}"));
        let run = bin()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(&out)
            .args(["--device", name, "--format", format])
            .args(flags)
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "{name} {format}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        out
    };
    let png = convert("png");
    let mut args = vec![profile.into_os_string(), png.into_os_string()];
    let formats: Vec<&str> = d
        .encodings
        .iter()
        .map(|f| f.name())
        .filter(|&f| f != "png")
        .collect();
    for f in &formats {
        let mut a = std::ffi::OsString::from(format!("{f}="));
        a.push(convert(f));
        args.push(a);
    }
    let out = Command::new("python3")
        .arg("-c")
        .arg(DECODER)
        .args(&args)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{name}: {text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(' ').collect();
    let (w, h): (usize, usize) = (head[1].parse().unwrap(), head[2].parse().unwrap());
    let used: usize = head[6].parse().unwrap();
    // The picture is fitted into the panel (or padded to it): one side is the panel's (the
    // caller checks the other).
    assert!(
        w <= d.width && h <= d.height && (w == d.width || h == d.height),
        "{name}: {w}x{h}"
    );
    assert_eq!(head[4], d.inks.len().to_string(), "{name}");
    // Every built-in gives its colours in sRGB (none in Lab): the whole PLTE was checked.
    assert_eq!(head[8], d.inks.len().to_string(), "{name}: PLTE checked");
    assert!(used >= 2.min(d.inks.len()), "{name}: {used} inks used");
    // One `equal` line for every encoding, in order.
    let decoded: Vec<&str> = lines.collect();
    assert_eq!(decoded.len(), formats.len(), "{name}: {text}");
    for (line, f) in decoded.iter().zip(&formats) {
        assert_eq!(*line, format!("{f} equal {w} {h}"), "{name}");
    }
    Some((w, h))
}

/// The size the 320x240 sample is fitted to on a panel: 4:3 into the panel, within a pixel.
fn fits(got: Option<(usize, usize)>, want: (usize, usize)) {
    if let Some((w, h)) = got {
        assert!(
            w.abs_diff(want.0) <= 1 && h.abs_diff(want.1) <= 1,
            "{w}x{h}, want {want:?}"
        );
    }
}

#[test]
fn spectra6_raw_and_header_decode_to_the_png_indices() {
    // Six inks with codes 0, 1, 2, 3, 5, 6 at 4 bits a pixel.
    fits(check_device("spectra6-7in3-v2"), (640, 480));
    // By default the picture is padded to the panel's size.
    fits(check_device_with("spectra6-7in3-v2", &[]), (800, 480));
}

#[test]
fn the_decoder_sees_one_changed_pixel() {
    // The check can fail: one nibble of a raw buffer changed is reported at its pixel.
    if !have_tool("python3", "python3", "panel_decode mutation") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/raytrace.png");
    let profile = dir.path().join("p.toml");
    let shown = bin()
        .args(["devices", "show", "bwry-4in2"])
        .output()
        .unwrap();
    std::fs::write(&profile, &shown.stdout).unwrap();
    let (png, raw) = (dir.path().join("a.png"), dir.path().join("a.raw"));
    for out in [&png, &raw] {
        bin()
            .arg("convert")
            .arg(&input)
            .arg("-o")
            .arg(out)
            .args(["--device", "bwry-4in2"])
            .assert()
            .success();
    }
    let mut bytes = std::fs::read(&raw).unwrap();
    // Row 2 (100 bytes a row at 2 bits), byte 7: pixels 28..31; flip the first one's low bit.
    bytes[2 * 100 + 7] ^= 0x40;
    std::fs::write(&raw, bytes).unwrap();
    let out = Command::new("python3")
        .arg("-c")
        .arg(DECODER)
        .arg(&profile)
        .arg(&png)
        .arg(format!("raw={}", raw.display()))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.contains("raw differ at 1 pixels, first 28,2:"),
        "{text}"
    );
}

#[test]
fn bwry_two_bit_raw_decodes_to_the_png_indices() {
    fits(check_device("bwry-4in2"), (400, 300));
}

#[test]
fn three_colour_planes_decode_to_the_png_indices() {
    // The black plane, then the red plane.
    fits(check_device("hanshow-bwr"), (171, 128));
}

#[test]
fn mono_planes_decode_to_the_png_indices() {
    fits(check_device("mono-4in26"), (640, 480));
}

#[test]
fn four_and_sixteen_greys_decode_to_the_png_indices() {
    fits(check_device("grey4-4in2"), (400, 300));
    // Nibbles (even pixel low), raw and h at 4 bits.
    fits(check_device("grey16-6in"), (800, 600));
}

#[test]
fn nominal_seven_colour_panel_decodes_to_the_png_indices() {
    fits(check_device("acep7-5in65"), (597, 448));
}
