//! Cost of one `eval`, `sample` and `pdf` call of each hair BSDF (targets: eval < 100 ns, sample < 200 ns;
//! Chiang et al. 2016 has none).
//!
//! `cargo bench -p cuticle-bench --bench bsdf`. Each measurement runs a batch of 1024 calls on precomputed random directions (uniform
//! on the sphere, local hair frame) and random numbers, so criterion's time per iteration / 1024 is the time per call;
//! the reported throughput (elements/s) is calls per second. Single thread, `bench` profile (opt-level 3).
//! A checksum of the results is returned to `black_box` so no call can be optimised away.

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use cuticle::bsdf::chiang::{directions, Chiang, ChiangParams, ChiangView, ViewLanes, LANES};
use cuticle::bsdf::ishair::{IsHair, IsHairParams, LobeSelection};
use cuticle::bsdf::kajiya_kay::{KajiyaKay, KajiyaKayParams};
use cuticle::bsdf::lanes::{self as fibre_lanes, Fibre};
use cuticle::bsdf::marschner::{Marschner, MarschnerParams};
use cuticle::bsdf::{Bsdf, Sampling};
use cuticle::util::sampling::uniform_sphere;
use glam::Vec3;
use rand::Rng;
use rand_pcg::Pcg32;
use wide::f32x8;

/// Calls per measured iteration.
const BATCH: usize = 1024;

struct Inputs {
    wo: Vec<Vec3>,
    wi: Vec<Vec3>,
    u: Vec<[f32; 3]>,
}

fn inputs() -> Inputs {
    let mut rng = Pcg32::new(2024, 1);
    let dir = |rng: &mut Pcg32| uniform_sphere(rng.random::<f32>(), rng.random::<f32>());
    let wo = (0..BATCH).map(|_| dir(&mut rng)).collect();
    let wi = (0..BATCH).map(|_| dir(&mut rng)).collect();
    let u = (0..BATCH).map(|_| rng.random()).collect();
    Inputs { wo, wi, u }
}

fn bench_model(c: &mut Criterion, name: &str, model: &dyn Bsdf, x: &Inputs) {
    let mut g = c.benchmark_group(name);
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("eval", |b| {
        b.iter(|| {
            let mut acc = Vec3::ZERO;
            for k in 0..BATCH {
                acc += model.eval(black_box(x.wo[k]), black_box(x.wi[k]));
            }
            acc
        })
    });
    g.bench_function("sample", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for k in 0..BATCH {
                if let Some(s) = model.sample(black_box(x.wo[k]), black_box(x.u[k])) {
                    acc += s.pdf + s.weight.x;
                }
            }
            acc
        })
    });
    g.bench_function("pdf", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for k in 0..BATCH {
                acc += model.pdf(black_box(x.wo[k]), black_box(x.wi[k]));
            }
            acc
        })
    });
    g.finish();
}

fn bsdfs(c: &mut Criterion) {
    let x = inputs();
    let kk = KajiyaKay::from_params(KajiyaKayParams::default()).unwrap();
    bench_model(c, "kajiya-kay", &kk, &x);
    bench_kajiya_kay_lanes(c, &kk, &x);
    for sampling in [
        Sampling::ExactPdf,
        Sampling::ClampAndFlip,
        Sampling::Uniform,
    ] {
        let m = Marschner::new(MarschnerParams {
            sampling,
            ..Default::default()
        })
        .unwrap();
        bench_model(c, &format!("marschner-{}", sampling.name()), &m, &x);
    }
    for selection in [LobeSelection::Uniform, LobeSelection::ByEnergy] {
        let m = IsHair::new(IsHairParams {
            selection,
            ..Default::default()
        })
        .unwrap();
        bench_model(c, &format!("ishair-{selection:?}").to_lowercase(), &m, &x);
    }
    // Chiang et al. 2016 with its defaults (pbrt-v4's: eumelanin 1.3, βm = βn = 0.3, α = 2°, η = 1.55) at one
    // offset across the fibre (the cost does not depend on h).
    let chiang = Chiang::new(ChiangParams::default()).unwrap();
    bench_model(c, "chiang", &chiang.at(0.3), &x);
    bench_chiang_lanes(c, &chiang, &x);
}

/// Chiang's eval on its own (the views taken beforehand, as a shading point reuses its view): one shading point at
/// a time (`Chiang::eval_viewed`, the renderer's path) against eight at once (`Chiang::eval_lanes`, step 1 of
/// `docs/design/wavefront.md`), on the same 1024 (view, ωi) pairs with random offsets h.
fn bench_chiang_lanes(c: &mut Criterion, chiang: &Chiang, x: &Inputs) {
    let mut rng = Pcg32::new(2026, 12);
    let views: Vec<ChiangView> = (0..BATCH)
        .map(|k| chiang.at(rng.random_range(-1.0f32..=1.0)).viewed(x.wo[k]))
        .collect();
    let lanes: Vec<(ViewLanes, [f32x8; 3])> = views
        .chunks_exact(LANES)
        .zip(x.wi.chunks_exact(LANES))
        .map(|(v, w)| {
            (
                ViewLanes::new(v.try_into().unwrap()),
                directions(w.try_into().unwrap()),
            )
        })
        .collect();
    let mut g = c.benchmark_group("chiang-lanes");
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("eval one at a time", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for (v, &wi) in views.iter().zip(&x.wi) {
                let (f, pdf) = chiang.eval_viewed(black_box(v), black_box(wi));
                acc += f.sum().x + pdf;
            }
            acc
        })
    });
    g.bench_function("eval eight at once", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for (v, wi) in &lanes {
                let e = chiang.eval_lanes(black_box(v), black_box(wi));
                acc += (e.r[0] + e.tt[0] + e.trt[0] + e.pdf).reduce_add();
            }
            acc
        })
    });
    g.finish();
}

/// Kajiya-Kay's generic code (`Fibre`) one shading point at a time (`R = f32`, what its `Bsdf` runs) against eight at
/// once (`R = f32x8`), on the inputs of the `kajiya-kay` group: each call takes the view of ωo and then evaluates
/// (f per lobe and the pdf, what a light sample needs) or samples, as the scalar `eval`, `pdf` and `sample` do.
fn bench_kajiya_kay_lanes(c: &mut Criterion, kk: &KajiyaKay, x: &Inputs) {
    const L: usize = fibre_lanes::LANES;
    let pack = |w: &[Vec3]| fibre_lanes::directions(w.try_into().unwrap());
    let lanes: Vec<([f32x8; 3], [f32x8; 3], [f32x8; 3])> = (0..BATCH / L)
        .map(|b| {
            let r = b * L..(b + 1) * L;
            let u: [f32x8; 3] =
                std::array::from_fn(|k| f32x8::new(std::array::from_fn(|j| x.u[b * L + j][k])));
            (pack(&x.wo[r.clone()]), pack(&x.wi[r]), u)
        })
        .collect();
    let mut g = c.benchmark_group("kajiya-kay-lanes");
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("eval+pdf one at a time", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for k in 0..BATCH {
                let view = kk.view(0.0, black_box(x.wo[k]).to_array());
                let e = kk.eval_view(&view, black_box(x.wi[k]).to_array());
                acc += e.lobes.r[0] + e.lobes.diffuse[0] + e.pdf;
            }
            acc
        })
    });
    g.bench_function("eval+pdf eight at once", |b| {
        b.iter(|| {
            let mut acc = f32x8::ZERO;
            for (wo, wi, _) in &lanes {
                let view = kk.view(f32x8::ZERO, *black_box(wo));
                let e = kk.eval_view(&view, *black_box(wi));
                acc += e.lobes.r[0] + e.lobes.diffuse[0] + e.pdf;
            }
            acc.reduce_add()
        })
    });
    g.bench_function("sample eight at once", |b| {
        b.iter(|| {
            let mut acc = f32x8::ZERO;
            for (wo, _, u) in &lanes {
                let view = kk.view(f32x8::ZERO, *black_box(wo));
                let s = kk.sample_view(&view, *black_box(u));
                acc += s.eval.pdf + s.eval.lobes.r[0] + s.eval.lobes.diffuse[0] + s.wi[0];
            }
            acc.reduce_add()
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    // 2-core machine, short runs: 2 s per measurement after 1 s warm-up is enough for ±1% on these loops.
    config = Criterion::default().warm_up_time(std::time::Duration::from_secs(1)).measurement_time(std::time::Duration::from_secs(2)).sample_size(50);
    targets = bsdfs
}
criterion_main!(benches);
