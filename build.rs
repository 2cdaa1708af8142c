//! Embeds every mask file in masks/ into the binary, named by file stem.
use std::{env, fs, path::Path};

fn main() {
    let dir = Path::new("masks");
    println!("cargo:rerun-if-changed=masks");
    let mut names: Vec<String> = fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "mask"))
                .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    let mut out = String::from("/// Built-in masks: (name, file text), sorted by name.\npub static BUILTIN_MASKS: &[(&str, &str)] = &[\n");
    for n in &names {
        let path = fs::canonicalize(dir.join(format!("{n}.mask"))).unwrap();
        out.push_str(&format!(
            "    ({n:?}, include_str!({:?})),\n",
            path.display().to_string()
        ));
    }
    out.push_str("];\n");
    let dest = Path::new(&env::var("OUT_DIR").unwrap()).join("builtin_masks.rs");
    fs::write(dest, out).unwrap();
}
