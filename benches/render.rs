//! Renderer speed: the 512×512 ray-traced scene at 16 jittered rays a pixel (goal: under a
//! second on 2 cores), and the z-buffered shading scene.
//!
//! cargo bench --bench render

use halftone::render::{render, Antialias, RenderOptions, Scene};

fn main() {
    divan::main();
}

#[divan::bench(sample_count = 5, sample_size = 1)]
fn raytrace_512_jitter16(bencher: divan::Bencher) {
    let scene = Scene::builtin("raytrace").unwrap();
    let opts = RenderOptions {
        size: Some((512, 512)),
        aa: Some(Antialias::Jitter),
    };
    bencher.bench(|| render(divan::black_box(&scene), &opts));
}

#[divan::bench(sample_count = 5, sample_size = 1)]
fn raytrace_512_one_ray(bencher: divan::Bencher) {
    let scene = Scene::builtin("raytrace").unwrap();
    let opts = RenderOptions {
        size: Some((512, 512)),
        aa: Some(Antialias::None),
    };
    bencher.bench(|| render(divan::black_box(&scene), &opts));
}

#[divan::bench(sample_count = 5, sample_size = 1)]
fn zbuffer_shading_512(bencher: divan::Bencher) {
    let scene = Scene::builtin("shading").unwrap();
    let opts = RenderOptions {
        size: Some((512, 192)),
        aa: Some(Antialias::Jitter),
    };
    bencher.bench(|| render(divan::black_box(&scene), &opts));
}
