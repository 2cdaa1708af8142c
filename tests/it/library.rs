//! The library's boundary: `-` is a file name like any other (standard input and output
//! are the binary's), messages name option fields, and a book written to a writer is the
//! book written to a file.

use std::path::{Path, PathBuf};

use halftone::{Converter, Error, Format, Options};

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("samples")
        .join(name)
}

#[test]
fn dash_is_a_file_name_not_standard_input() {
    // Were `-` standard input, this would read the test's stdin (empty or a terminal).
    let e = halftone::convert("-", &Options::default()).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
    let msg = e.to_string();
    assert!(
        msg.starts_with("-:") && msg.contains("No such file"),
        "{msg}"
    );
    let e = halftone::io::read_image(Path::new("-"), &Default::default()).unwrap_err();
    assert!(e.to_string().contains("No such file"), "{e}");
}

#[test]
fn messages_name_fields_not_flags() {
    let opts = Options {
        width: Some(100),
        size: Some("2in".into()),
        dpi: Some(300.0),
        ..Default::default()
    };
    let e = halftone::convert(sample("kd-series.png"), &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("`width`") && e.contains("`size`"), "{e}");
    assert!(!e.contains("--"), "{e}");
    let e = halftone::MaxMemory::parse("lots").unwrap_err().to_string();
    assert!(e.contains("`max_memory`") && !e.contains("--"), "{e}");
}

/// Each input a page of a PDF book.
fn pages<'a>(
    conv: &'a Converter,
    inputs: &'a [PathBuf],
    name: PathBuf,
) -> impl FnMut(
    &mut dyn halftone::io::sink::PageEncoder,
    &mut dyn std::io::Write,
) -> halftone::Result<bool>
       + 'a {
    let mut next = inputs.iter();
    move |enc, out| {
        let Some(input) = next.next() else {
            return Ok(false);
        };
        conv.add_page(input.as_path(), Format::Pdf, enc, out, &name)?;
        Ok(true)
    }
}

#[test]
fn a_book_to_a_writer_is_the_book_to_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let opts = Options {
        dpi: Some(300.0),
        ..Default::default()
    };
    let conv = Converter::new(&opts).unwrap();
    let write = opts.write_options(Format::Pdf);
    let inputs = [sample("kd-series.png"), sample("ka-series.png")];
    let file = dir.path().join("book.pdf");
    let n = halftone::io::write_pages(&file, &write, pages(&conv, &inputs, file.clone())).unwrap();
    assert_eq!(n, 2);
    let mut buf = Vec::new();
    let name = PathBuf::from("<bytes>");
    let n =
        halftone::io::write_pages_to(&mut buf, &name, &write, pages(&conv, &inputs, name.clone()))
            .unwrap();
    assert_eq!(n, 2);
    assert_eq!(std::fs::read(&file).unwrap(), buf);
    // A one-image format is refused before anything is written.
    let png = opts.write_options(Format::Png);
    let mut buf = Vec::new();
    let e =
        halftone::io::write_pages_to(&mut buf, &name, &png, pages(&conv, &inputs, name.clone()))
            .unwrap_err();
    assert!(
        e.to_string().contains("holds one image") && buf.is_empty(),
        "{e}"
    );
}

/// Runs the binary with `stdin` as its standard input; returns its standard output.
fn run_with_stdin(args: &[&str], stdin: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_halftone"))
        .args(args)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut pipe = child.stdin.take().unwrap();
    let data = stdin.to_vec();
    let writer = std::thread::spawn(move || {
        let _ = pipe.write_all(&data);
    });
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

#[test]
fn the_binary_reads_and_writes_dash_as_standard_streams() {
    let dir = tempfile::tempdir().unwrap();
    let png = sample("kd-series.png");
    let png_bytes = std::fs::read(&png).unwrap();
    let file = dir.path().join("kd.pbm");
    let p = |p: &Path| p.to_str().unwrap().to_string();
    crate::common::ok(&[
        "convert".as_ref(),
        png.as_os_str(),
        "-o".as_ref(),
        file.as_os_str(),
    ]);
    let want = std::fs::read(&file).unwrap();
    // convert - -o -
    let got = run_with_stdin(&["convert", "-", "-o", "-", "--format", "pbm"], &png_bytes);
    assert!(got == want, "convert through standard streams differs");
    // compare with the original from standard input: the figures of the file's.
    let from_file = crate::common::ok(&["compare".as_ref(), png.as_os_str(), file.as_os_str()]);
    let from_stdin = run_with_stdin(&["compare", "-", &p(&file)], &png_bytes);
    assert_eq!(String::from_utf8(from_stdin).unwrap(), from_file);
    // batch -o - writes the book to standard output, the same bytes as to a file.
    let book = dir.path().join("book.pdf");
    let k = sample("ka-series.png");
    let args = |out: &str| {
        vec![
            "batch".to_string(),
            p(&png),
            p(&k),
            "-o".into(),
            out.into(),
            "--format".into(),
            "pdf".into(),
            "--dpi".into(),
            "300".into(),
        ]
    };
    let a = args(&p(&book));
    let a: Vec<&std::ffi::OsStr> = a.iter().map(|s| s.as_ref()).collect();
    crate::common::ok(&a);
    let a = args("-");
    let a: Vec<&str> = a.iter().map(|s| s.as_str()).collect();
    assert!(run_with_stdin(&a, b"") == std::fs::read(&book).unwrap());
}
