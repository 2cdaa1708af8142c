//! The sample-scene renderer: samples reproduced, the lecture's tables and formulas seen in
//! rendered pictures, antialiasing, determinism, scene-file errors and the CLI.

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use halftone::render::{
    self, jitter_offset, sample_picture, Antialias, Depth, Frame, RenderOptions, Scene, BUILTIN,
};

fn scene(text: &str) -> Scene {
    Scene::from_toml(text, Path::new("test.toml")).unwrap()
}

fn draw(s: &Scene, w: usize, h: usize, aa: Antialias) -> Frame {
    render::render(
        s,
        &RenderOptions {
            size: Some((w, h)),
            aa: Some(aa),
        },
    )
}

/// Every built-in scene, rendered at its own size and antialiasing, matches its PNG in
/// samples/ to within one 8-bit code per channel (exact on the machine that made them; the
/// one-code slack absorbs libm differences between platforms).
#[test]
fn renderer_reproduces_the_samples() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (name, _, _) in BUILTIN {
        let s = Scene::builtin(name).unwrap();
        let frame = render::render(&s, &RenderOptions::default());
        let path = root.join("samples").join(format!("{name}.png"));
        let png = image::open(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .to_rgb8();
        assert_eq!(
            (png.width() as usize, png.height() as usize),
            (frame.width, frame.height),
            "{name}"
        );
        let ours = frame.to_srgb8();
        let worst = ours
            .iter()
            .zip(png.as_raw())
            .map(|(a, b)| a.abs_diff(*b))
            .max()
            .unwrap();
        assert!(
            worst <= 1,
            "{name}: differs from samples/{name}.png by {worst} codes"
        );
    }
}

#[test]
fn builtin_list_matches_scene_files() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let names: Vec<&str> = BUILTIN.iter().map(|b| b.0).collect();
    for want in [
        "kd-series",
        "ka-series",
        "ns-series",
        "shading",
        "polyhedra",
        "raytrace",
        "color-balls",
        "warn-studio",
    ] {
        assert!(names.contains(&want), "{want}");
    }
    for (name, _, text) in BUILTIN {
        let file = std::fs::read_to_string(root.join("scenes").join(format!("{name}.toml")));
        assert_eq!(file.unwrap(), *text, "{name}");
    }
    // Every example scene file loads.
    for entry in std::fs::read_dir(root.join("scenes")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        }
    }
}

/// The lecture's table of balls and lights, in the rendered `color-balls` scene: the centre
/// of each ball, left to right.
#[test]
fn color_balls_show_the_lecture_table() {
    let s = Scene::builtin("color-balls").unwrap();
    let (w, h) = (120, 24);
    let f = draw(&s, w, h, Antialias::None);
    // Balls at x = −10 + 4i on a 24-unit-wide view: picture x = (i + 0.5)·w/6; probe
    // slightly up and left of centre, towards the light.
    let probe = |i: usize| f.get(((i as f64 + 0.4) * w as f64 / 6.0) as usize, h / 2 - 2);
    let class = |c: [f32; 3]| c.map(|v| v > 0.05);
    let table = [
        ("white ball, red light", [true, false, false]),
        ("red ball, white light", [true, false, false]),
        ("red ball, green light", [false, false, false]),
        ("purple ball, blue light", [false, false, true]),
        ("yellow ball, aqua light", [false, true, false]),
        ("red ball, magenta light", [true, false, false]),
    ];
    for (i, (what, want)) in table.iter().enumerate() {
        assert_eq!(class(probe(i)), *want, "{what}: {:?}", probe(i));
    }
}

const TWO_SPHERES: &str = r#"
size = [64, 48]
renderer = "RENDERER"
ambient = [0.0, 0.0, 0.0]
[camera]
eye = [0.0, 0.0, 10.0]
look_at = [0.0, 0.0, 0.0]
fov = 30
[[light]]
kind = "directional"
direction = [0.0, 0.0, -1.0]
[material.red]
color = [1.0, 0.0, 0.0]
ka = 0.0
kd = 1.0
ks = 0.0
[material.blue]
color = [0.0, 0.0, 1.0]
ka = 0.0
kd = 1.0
ks = 0.0
[[sphere]]
center = [0.0, 0.0, -3.0]
radius = 2.0
material = "FAR"
[[sphere]]
center = [0.5, 0.0, 1.0]
radius = 1.0
material = "NEAR"
"#;

/// The nearer surface wins whatever the order of the objects, in both renderers (the
/// z-buffer and the nearest ray hit).
#[test]
fn nearest_surface_is_visible() {
    for renderer in ["raytrace", "zbuffer"] {
        for (far, near) in [("red", "blue"), ("blue", "red")] {
            let text = TWO_SPHERES
                .replace("RENDERER", renderer)
                .replace("FAR", far)
                .replace("NEAR", near);
            let f = draw(&scene(&text), 64, 48, Antialias::None);
            let c = f.get(36, 24); // in front of both, on the near sphere
            let want_red = near == "red";
            assert_eq!(c[0] > 0.5, want_red, "{renderer} {near}: {c:?}");
            assert_eq!(c[2] > 0.5, !want_red, "{renderer} {near}: {c:?}");
            // Lambert: facing the light straight on, the sphere's centre is at kd·Il = 1.
            let centre = f.get(32 + 4, 24);
            assert!(centre[0].max(centre[2]) > 0.9, "{renderer}");
        }
    }
}

/// Flat shading gives one intensity per polygon; Gouraud interpolates (many values) but
/// misses the highlight that Phong shading, applying the model per pixel, finds.
#[test]
fn flat_gouraud_phong_differ_as_the_lecture_says() {
    let s = Scene::builtin("shading").unwrap();
    let (w, h) = s.size;
    let f = draw(&s, w, h, Antialias::None);
    // Pixels of the k-th sphere: those that differ from the background at the picture's
    // left edge on the same row.
    let third = |k: usize| {
        let mut vals = Vec::new();
        for y in 0..h {
            let bg = f.get(0, y)[1];
            for x in k * w / 3..(k + 1) * w / 3 {
                let v = f.get(x, y)[1];
                if v != bg {
                    vals.push(v);
                }
            }
        }
        vals
    };
    let distinct = |v: &[f32]| {
        let mut v: Vec<u32> = v.iter().map(|x| x.to_bits()).collect();
        v.sort_unstable();
        v.dedup();
        v.len()
    };
    let max = |v: &[f32]| v.iter().copied().fold(0.0f32, f32::max);
    let (flat, gouraud, phong) = (third(0), third(1), third(2));
    // 6 stacks × 12 slices = 72 faces, about half of them visible.
    assert!(distinct(&flat) <= 40, "flat: {}", distinct(&flat));
    assert!(distinct(&flat) >= 20, "flat: {}", distinct(&flat));
    assert!(distinct(&gouraud) > 1000);
    assert!(distinct(&phong) > 1000);
    // The highlight: Phong's peak stands well above Gouraud's.
    assert!(
        max(&phong) > max(&gouraud) + 0.2,
        "{} {}",
        max(&phong),
        max(&gouraud)
    );
}

const SHADOW: &str = r#"
size = [40, 40]
ambient = [0.2, 0.2, 0.2]
shadows = SHADOWS
[camera]
eye = [0.0, 8.0, 0.1]
look_at = [0.0, 0.0, 0.0]
fov = 60
[[light]]
kind = "point"
position = [0.0, 20.0, 0.0]
[material.floor]
ka = 1.0
kd = 1.0
ks = 0.0
[[plane]]
point = [0.0, -1.0, 0.0]
normal = [0.0, 1.0, 0.0]
material = "floor"
[[sphere]]
center = [3.0, 1.0, 0.0]
radius = 0.5
material = "floor"
"#;

/// A shadow ray blocked by the sphere leaves the floor beneath it with ambient light only.
#[test]
fn shadow_rays_darken_the_floor_under_a_sphere() {
    let lit = draw(
        &scene(&SHADOW.replace("SHADOWS", "false")),
        40,
        40,
        Antialias::None,
    );
    let dark = draw(
        &scene(&SHADOW.replace("SHADOWS", "true")),
        40,
        40,
        Antialias::None,
    );
    // Looking straight down: the floor point under the sphere (x = 3) is beside it in the
    // picture; find a pixel that changed and check it fell to ambient (ka·Ia = 0.2).
    let mut shadowed = 0;
    for y in 0..40 {
        for x in 0..40 {
            let (a, b) = (lit.get(x, y)[0], dark.get(x, y)[0]);
            assert!(b <= a + 1e-6);
            if b < a - 1e-3 {
                shadowed += 1;
                assert!((b - 0.2).abs() < 1e-4, "{b}");
            }
        }
    }
    assert!(shadowed > 4, "{shadowed}");
}

const LENS: &str = r#"
size = [48, 48]
ambient = [0.0, 0.0, 0.0]
background = [1.0, 1.0, 1.0]
background_bottom = [0.0, 0.0, 0.0]
max_depth = 8
[camera]
eye = [0.0, 0.0, 10.0]
look_at = [0.0, 0.0, 0.0]
fov = 20
[material.glass]
ka = 0.0
kd = 0.0
ks = 0.0
transmit = 1.0
ior = IOR
[[sphere]]
center = [0.0, 0.0, 0.0]
radius = 1.2
material = "glass"
"#;

/// Refraction by Snell's law: a glass ball of index 1 is invisible; of index 1.5 it is a
/// lens that turns the background upside down (top of the ball sees the dark bottom).
#[test]
fn refraction_through_a_glass_ball() {
    let bg = draw(&scene(&LENS.replace("IOR", "1.0")), 48, 48, Antialias::None);
    let mut nothing = scene(&LENS.replace("IOR", "1.0"));
    nothing.spheres.clear();
    let sky = draw(&nothing, 48, 48, Antialias::None);
    for (a, b) in bg.pixels.iter().zip(&sky.pixels) {
        assert!((a - b).abs() < 1e-5, "{a} {b}");
    }
    let lens = draw(&scene(&LENS.replace("IOR", "1.5")), 48, 48, Antialias::None);
    let (top, bottom) = (lens.get(24, 18)[0], lens.get(24, 30)[0]);
    assert!(top < sky.get(24, 18)[0] && bottom > sky.get(24, 30)[0]);
    assert!(top < bottom, "top {top} bottom {bottom}");
}

const MIRROR: &str = r#"
size = [32, 32]
ambient = [1.0, 1.0, 1.0]
background = [0.0, 0.0, 0.0]
attenuation = ATT
[camera]
eye = [0.0, 0.0, 10.0]
look_at = [0.0, 0.0, 0.0]
fov = 24
[material.mirror]
ka = 0.0
kd = 0.0
ks = 0.0
reflect = 1.0
[material.lamp]
ka = 1.0
kd = 0.0
ks = 0.0
[[plane]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "mirror"
[[sphere]]
center = [2.2, 0.0, 3.0]
radius = 0.5
material = "lamp"
"#;

/// A mirror shows what is in front of it, and the ray tree attenuates the reflection with
/// the distance the reflected ray travels (from the mirror at z = 0 to the ball's surface,
/// 2.5 to 3.5 units). The ball itself is outside the picture: only its image is seen.
#[test]
fn mirror_reflection_attenuates_with_distance() {
    let near = draw(
        &scene(&MIRROR.replace("ATT", "[1.0, 0.0, 0.0]")),
        32,
        32,
        Antialias::None,
    );
    let far = draw(
        &scene(&MIRROR.replace("ATT", "[1.0, 0.2, 0.0]")),
        32,
        32,
        Antialias::None,
    );
    let mut seen = 0;
    for y in 0..32 {
        for x in 0..32 {
            let (a, b) = (near.get(x, y)[0], far.get(x, y)[0]);
            if a > 0.0 {
                // Unattenuated, the ball lit by ambient only is exactly ka·Ia = 1.
                assert!((a - 1.0).abs() < 1e-6, "{a}");
                assert!((1.0 / 1.7..=1.0 / 1.5).contains(&b), "{b}");
                seen += 1;
            }
        }
    }
    assert!(seen >= 4, "{seen}");
    // The depth limit: with no secondary rays allowed the mirror shows nothing.
    let text = MIRROR.replace("ATT", "[1.0, 0.0, 0.0]") + "";
    let text = text.replace("attenuation =", "max_depth = 0\nattenuation =");
    let flat = draw(&scene(&text), 32, 32, Antialias::None);
    assert!(flat.pixels.iter().all(|&v| v == 0.0));
}

/// Jitter: 16 offsets per pixel, each in (−0.5, 0.5), the same on every call, different
/// between pixels.
#[test]
fn jitter_is_deterministic_and_in_range() {
    let mut all = Vec::new();
    for s in 0..16 {
        let (dx, dy) = jitter_offset(3, 7, s);
        assert!(dx > -0.5 && dx < 0.5 && dy > -0.5 && dy < 0.5);
        assert_eq!((dx, dy), jitter_offset(3, 7, s));
        all.push((dx, dy));
    }
    assert_ne!(jitter_offset(3, 7, 0), jitter_offset(7, 3, 0));
    assert_ne!(jitter_offset(3, 7, 0), jitter_offset(3, 8, 0));
    let mean: f64 = all.iter().map(|p| p.0).sum::<f64>() / 16.0;
    assert!(mean.abs() < 0.25);
}

/// Same picture whatever the number of threads.
#[test]
fn output_independent_of_thread_count() {
    let s = Scene::builtin("raytrace").unwrap();
    let run = |s: &Scene, threads: usize, aa: Antialias| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| draw(s, 64, 48, aa))
    };
    for aa in [Antialias::Jitter, Antialias::Adaptive] {
        let one = run(&s, 1, aa);
        assert_eq!(one, run(&s, 2, aa), "{aa:?}");
        assert_eq!(one, run(&s, 3, aa), "{aa:?}");
    }
    let z = Scene::builtin("shading").unwrap();
    assert_eq!(run(&z, 1, Antialias::Super), run(&z, 2, Antialias::Super));
}

/// Antialiasing: rays through corners are shared between pixels; adaptive sampling adds
/// rays only where corners differ, never more than 256 a pixel; jitter fires 16.
#[test]
fn antialiasing_ray_counts() {
    let count = |aa: Antialias, f: &(dyn Fn(f64, f64) -> render::Rgb + Sync)| {
        let n = AtomicUsize::new(0);
        let out = sample_picture(8, 6, aa, &|x, y| {
            n.fetch_add(1, Ordering::Relaxed);
            f(x, y)
        });
        (n.into_inner(), out)
    };
    let flat = |_: f64, _: f64| render::Rgb::new(0.5, 0.5, 0.5);
    assert_eq!(count(Antialias::None, &flat).0, 48);
    assert_eq!(count(Antialias::Super, &flat).0, 9 * 7);
    assert_eq!(count(Antialias::Adaptive, &flat).0, 9 * 7);
    assert_eq!(count(Antialias::Jitter, &flat).0, 48 * 16);
    // A fine checkerboard: adaptive subdivides every pixel, to its budget at most.
    let fine = |x: f64, y: f64| {
        let v = ((x * 37.0).floor() + (y * 41.0).floor()) as i64 % 2;
        render::Rgb::new(v as f64, v as f64, v as f64)
    };
    let (n, out) = count(Antialias::Adaptive, &fine);
    assert!(n > 9 * 7 + 48 * 100, "{n}");
    assert!(n <= 9 * 7 + 48 * 252, "{n}");
    // And the averages come out near the checkerboard's mean, unlike single rays.
    let mean = out.iter().map(|&v| v as f64).sum::<f64>() / out.len() as f64;
    assert!((mean - 0.5).abs() < 0.1, "{mean}");
    // A hard edge: corner supersampling gives the pixel it crosses an in-between value.
    let edge = |x: f64, _: f64| {
        let v = if x < 3.5 { 1.0 } else { 0.0 };
        render::Rgb::new(v, v, v)
    };
    let (_, none) = count(Antialias::None, &edge);
    let (_, sup) = count(Antialias::Super, &edge);
    assert!(none.iter().all(|&v| v == 0.0 || v == 1.0));
    assert_eq!(sup[3 * 3], 0.5);
}

/// 8- and 16-bit PNGs decode back to the sRGB codes of the frame.
#[test]
fn png_round_trip_8_and_16_bit() {
    let s = Scene::builtin("kd-series").unwrap();
    let f = draw(&s, 60, 16, Antialias::Super);
    let png8 = f.encode_png(Depth::Eight).unwrap();
    let img = image::load_from_memory(&png8).unwrap();
    assert_eq!(img.color(), image::ColorType::Rgb8);
    assert_eq!(img.to_rgb8().into_raw(), f.to_srgb8());
    let png16 = f.encode_png(Depth::Sixteen).unwrap();
    let img = image::load_from_memory(&png16).unwrap();
    assert_eq!(img.color(), image::ColorType::Rgb16);
    assert_eq!(img.to_rgb16().into_raw(), f.to_srgb16());
    // sRGB encoding of linear light: linear 0.5 is code 188, not 128.
    let mid = Frame {
        width: 1,
        height: 1,
        pixels: vec![0.5, 0.0, 1.5],
    };
    assert_eq!(mid.to_srgb8(), vec![188, 0, 255]);
}

fn parse_error(text: &str) -> String {
    Scene::from_toml(text, Path::new("scenes/bad.toml"))
        .unwrap_err()
        .to_string()
}

/// A bad scene file names the file and the line.
#[test]
fn scene_errors_name_the_line() {
    let base = "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\n";
    let e = parse_error(&format!("{base}\n[material.m]\ncolr = [1, 0, 0]\n"));
    assert!(e.starts_with("scenes/bad.toml:6: "), "{e}");
    assert!(e.contains("colr"), "{e}");
    let e = parse_error(&format!(
        "{base}\n\n[[sphere]]\ncenter = [0, 0, 0]\nradius = -1\n"
    ));
    assert!(e.starts_with("scenes/bad.toml:6: "), "{e}");
    assert!(e.contains("radius"), "{e}");
    let e = parse_error(&format!(
        "{base}[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"gold\"\n"
    ));
    assert!(
        e.starts_with("scenes/bad.toml:4: ") && e.contains("gold"),
        "{e}"
    );
    let e = parse_error(&format!("{base}[[light]]\nkind = \"laser\"\n"));
    assert!(
        e.starts_with("scenes/bad.toml:4: ") && e.contains("laser"),
        "{e}"
    );
    let e = parse_error(&format!("{base}[material.m]\nkd = 1.5\n"));
    assert!(
        e.starts_with("scenes/bad.toml:4: ") && e.contains("kd"),
        "{e}"
    );
    let e = parse_error("[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, \n");
    assert!(e.starts_with("scenes/bad.toml:3: "), "{e}");
    let e = parse_error(&format!(
        "size = [10, 10]\n\n{}",
        base.replace("[0, 0, 5]", "[0, 0, 0]")
    ));
    assert!(
        e.starts_with("scenes/bad.toml:3: ") && e.contains("eye"),
        "{e}"
    );
    let e = parse_error(&format!("size = [0, 10]\n{base}"));
    assert!(
        e.starts_with("scenes/bad.toml:1: ") && e.contains("size"),
        "{e}"
    );
    let e = parse_error("size = [10, 10]\n");
    assert!(
        e.starts_with("scenes/bad.toml:") && e.contains("camera"),
        "{e}"
    );
    let e = parse_error(&format!(
        "renderer = \"zbuffer\"\n{base}[[plane]]\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\n"
    ));
    assert!(
        e.starts_with("scenes/bad.toml:5: ") && e.contains("raytrace"),
        "{e}"
    );
}

/// The `halftone render` command, run as a user would.
mod cli {
    use assert_cmd::Command;

    fn halftone() -> Command {
        Command::cargo_bin("halftone").unwrap()
    }

    #[test]
    fn list_names_every_builtin_scene() {
        let mut cmd = halftone();
        let out = cmd.args(["render", "--list"]).assert().success();
        let text = String::from_utf8(out.get_output().stdout.clone()).unwrap();
        for (name, _, _) in halftone::render::BUILTIN {
            assert!(text.lines().any(|l| l.starts_with(name)), "{name}");
        }
    }

    #[test]
    fn renders_a_png_equal_to_the_library() {
        let mut cmd = halftone();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("kd.png");
        cmd.args(["render", "kd-series", "-o"])
            .arg(&out)
            .args(["--size", "50x12", "--aa", "super"])
            .assert()
            .success();
        let img = image::open(&out).unwrap();
        assert_eq!(img.color(), image::ColorType::Rgb8);
        let s = halftone::render::Scene::builtin("kd-series").unwrap();
        let f = halftone::render::render(
            &s,
            &halftone::render::RenderOptions {
                size: Some((50, 12)),
                aa: Some(halftone::render::Antialias::Super),
            },
        );
        assert_eq!(img.to_rgb8().into_raw(), f.to_srgb8());

        let out16 = dir.path().join("kd16.png");
        halftone()
            .args(["render", "kd-series", "-o"])
            .arg(&out16)
            .args(["--size", "20x6", "--depth", "16"])
            .assert()
            .success();
        assert_eq!(
            image::open(&out16).unwrap().color(),
            image::ColorType::Rgb16
        );
    }

    #[test]
    fn a_bad_scene_file_is_one_line_naming_file_and_line() {
        let mut cmd = halftone();
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.toml");
        std::fs::write(
            &bad,
            "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\n\n[material.m]\ncolr = [1, 0, 0]\n",
        )
        .unwrap();
        let out = cmd
            .args(["render"])
            .arg(&bad)
            .arg("-o")
            .arg(dir.path().join("x.png"))
            .assert()
            .failure();
        let err = String::from_utf8(out.get_output().stderr.clone()).unwrap();
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.contains(&format!("{}:6:", bad.display())), "{err}");
        assert!(err.contains("colr"), "{err}");
        assert!(!dir.path().join("x.png").exists());

        let out = halftone()
            .args(["render", "no-such-scene", "-o"])
            .arg(dir.path().join("y.png"))
            .assert()
            .failure();
        let err = String::from_utf8(out.get_output().stderr.clone()).unwrap();
        assert!(
            err.contains("no-such-scene") && !err.contains("panicked"),
            "{err}"
        );
        halftone()
            .args(["render", "kd-series", "-o", "z.png", "--size", "0x5"])
            .assert()
            .failure();
    }
}
