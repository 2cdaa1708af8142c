//! Embeds every mask file in masks/ and every device profile in devices/ into the binary,
//! named by file stem, and builds the small C layer over the system's libjpeg
//! (libjpeg-turbo) when its header is there.
use std::{env, fs, path::Path};

/// Compiles src/io/codec/jpeg_shim.c and links libjpeg, setting `cfg(halftone_libjpeg)`; without
/// libjpeg's header (Debian: libjpeg-dev) JPEG goes through the `image` crate alone.
/// `HALFTONE_NO_LIBJPEG=1`, or a build without the `libjpeg` feature, goes without it.
fn libjpeg() {
    println!("cargo::rustc-check-cfg=cfg(halftone_libjpeg)");
    println!("cargo:rerun-if-changed=src/io/codec/jpeg_shim.c");
    println!("cargo:rerun-if-env-changed=HALFTONE_NO_LIBJPEG");
    if env::var_os("HALFTONE_NO_LIBJPEG").is_some_and(|v| v != "0") {
        return;
    }
    // Only with the `libjpeg` feature, and never for WebAssembly (no system libraries).
    if env::var_os("CARGO_FEATURE_LIBJPEG").is_none()
        || env::var("CARGO_CFG_TARGET_ARCH").is_ok_and(|a| a == "wasm32")
    {
        return;
    }
    let built = cc::Build::new()
        .file("src/io/codec/jpeg_shim.c")
        .opt_level(2)
        .warnings(false)
        .cargo_warnings(false)
        .try_compile("halftone_jpeg_shim");
    if built.is_ok() {
        println!("cargo:rustc-link-lib=jpeg");
        println!("cargo:rustc-cfg=halftone_libjpeg");
    } else {
        println!("cargo:warning=libjpeg's header not found (apt-get install libjpeg-dev): JPEG is decoded by the image crate alone, without shrink-on-load");
    }
}

/// Writes `$OUT_DIR/FILE`: a static `NAME` listing every `DIR/*.EXT` file as (stem, text),
/// sorted by stem, each through `include_str!` so the build follows the files.
fn embed(dir: &str, ext: &str, doc: &str, name: &str, file: &str) {
    let dir = Path::new(dir);
    println!("cargo:rerun-if-changed={}", dir.display());
    let mut names: Vec<String> = fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == ext))
                .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    let mut out = format!(
        "/// {doc}: (name, file text), sorted by name.\npub static {name}: &[(&str, &str)] = &[\n"
    );
    for n in &names {
        let path = fs::canonicalize(dir.join(format!("{n}.{ext}"))).unwrap();
        out.push_str(&format!(
            "    ({n:?}, include_str!({:?})),\n",
            path.display().to_string()
        ));
    }
    out.push_str("];\n");
    let dest = Path::new(&env::var("OUT_DIR").unwrap()).join(file);
    fs::write(dest, out).unwrap();
}

fn main() {
    libjpeg();
    embed(
        "masks",
        "mask",
        "Built-in masks",
        "BUILTIN_MASKS",
        "builtin_masks.rs",
    );
    embed(
        "devices",
        "toml",
        "Built-in device profiles",
        "BUILTIN_DEVICES",
        "builtin_devices.rs",
    );
}
