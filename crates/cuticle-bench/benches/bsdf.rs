//! Cost of one `eval`, `sample` and `pdf` call of each hair BSDF (targets: eval < 100 ns, sample < 200 ns;
//! Chiang et al. 2016 has none).
//!
//! `cargo bench -p cuticle-bench --bench bsdf`. Each measurement runs a batch of 1024 calls on precomputed random directions (uniform
//! on the sphere, local hair frame) and random numbers, so criterion's time per iteration / 1024 is the time per call;
//! the reported throughput (elements/s) is calls per second. Single thread, `bench` profile (opt-level 3).
//! A checksum of the results is returned to `black_box` so no call can be optimised away.

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use cuticle::bsdf::chiang::{Chiang, ChiangParams, ChiangView};
use cuticle::bsdf::ishair::{IsHair, IsHairParams, LobeSelection};
use cuticle::bsdf::kajiya_kay::{KajiyaKay, KajiyaKayParams};
use cuticle::bsdf::lanes::{self as fibre, directions, Fibre, LANES};
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
    bench_marschner_lanes(c, &x);
    for selection in [LobeSelection::Uniform, LobeSelection::ByEnergy] {
        let m = IsHair::new(IsHairParams {
            selection,
            ..Default::default()
        })
        .unwrap();
        bench_model(c, &format!("ishair-{selection:?}").to_lowercase(), &m, &x);
    }
    bench_ishair_lanes(c, &IsHair::new(IsHairParams::default()).unwrap(), &x);
    // Chiang et al. 2016 with its defaults (pbrt-v4's: eumelanin 1.3, βm = βn = 0.3, α = 2°, η = 1.55) at one
    // offset across the fibre (the cost does not depend on h).
    let chiang = Chiang::new(ChiangParams::default()).unwrap();
    bench_model(c, "chiang", &chiang.at(0.3), &x);
    bench_chiang_lanes(c, &chiang, &x);
}

/// Chiang's eval and sample on their own (the hits prepared beforehand, as a shading point reuses its view): one
/// shading point at a time (`f32`, the scalar path) against eight at once (`f32x8`, the lanes), the same generic
/// code on the same 1024 (view, ωi, u) triples with random offsets h.
fn bench_chiang_lanes(c: &mut Criterion, chiang: &Chiang, x: &Inputs) {
    let mut rng = Pcg32::new(2026, 12);
    let h: Vec<f32> = (0..BATCH)
        .map(|_| rng.random_range(-1.0f32..=1.0))
        .collect();
    let views: Vec<ChiangView<f32>> = (0..BATCH)
        .map(|k| chiang.view(h[k], x.wo[k].to_array()))
        .collect();
    type Batch = (ChiangView<f32x8>, [f32x8; 3], [f32x8; 3]);
    let lanes: Vec<Batch> = (0..BATCH / LANES)
        .map(|b| {
            let r = b * LANES..(b + 1) * LANES;
            let hs = f32x8::new(h[r.clone()].try_into().unwrap());
            let view = chiang.view(hs, directions(x.wo[r.clone()].try_into().unwrap()));
            let u: [f32x8; 3] =
                std::array::from_fn(|c| f32x8::new(std::array::from_fn(|k| x.u[r.start + k][c])));
            (view, directions(x.wi[r].try_into().unwrap()), u)
        })
        .collect();
    let mut g = c.benchmark_group("chiang-lanes");
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("eval one at a time", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for (v, wi) in views.iter().zip(&x.wi) {
                let e = chiang.eval_view(black_box(v), black_box(wi.to_array()));
                acc += e.lobes.r[0] + e.lobes.tt[0] + e.lobes.trt[0] + e.pdf;
            }
            acc
        })
    });
    g.bench_function("eval eight at once", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for (v, wi, _) in &lanes {
                let e = chiang.eval_view(black_box(v), black_box(*wi));
                acc += (e.lobes.r[0] + e.lobes.tt[0] + e.lobes.trt[0] + e.pdf).reduce_add();
            }
            acc
        })
    });
    g.bench_function("sample one at a time", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for (v, u) in views.iter().zip(&x.u) {
                let s = chiang.sample_view(black_box(v), black_box(*u));
                acc += s.wi[0] + s.eval.pdf;
            }
            acc
        })
    });
    g.bench_function("sample eight at once", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for (v, _, u) in &lanes {
                let s = chiang.sample_view(black_box(v), black_box(*u));
                acc += (s.wi[0] + s.eval.pdf).reduce_add();
            }
            acc
        })
    });
    g.finish();
}

/// Marschner's eight-lane form (the generic code at `f32x8`, `bsdf::lanes::Fibre`) on the inputs of the
/// `marschner-*` groups, eight calls at a time: each call takes the view of its ωo and then evaluates or samples,
/// as the scalar `Bsdf` calls do, so time per element against theirs is the per-lane cost. `eval` reads f alone
/// (as `Bsdf::eval`), `eval+pdf` f and the pdf (as one `eval` and one `pdf` call), `sample` the sample.
fn bench_marschner_lanes(c: &mut Criterion, x: &Inputs) {
    let eight = |w: &[Vec3]| fibre::directions(w.try_into().unwrap());
    let wo: Vec<[f32x8; 3]> = x.wo.chunks_exact(fibre::LANES).map(eight).collect();
    let wi: Vec<[f32x8; 3]> = x.wi.chunks_exact(fibre::LANES).map(eight).collect();
    let u: Vec<[f32x8; 3]> =
        x.u.chunks_exact(fibre::LANES)
            .map(|u| std::array::from_fn(|c| f32x8::new(std::array::from_fn(|k| u[k][c]))))
            .collect();
    let h = f32x8::splat(0.0);
    let mut g = c.benchmark_group("marschner-lanes");
    g.throughput(Throughput::Elements(BATCH as u64));
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
        g.bench_function(format!("{}/eval", sampling.name()), |b| {
            b.iter(|| {
                let mut acc = f32x8::splat(0.0);
                for (wo, wi) in wo.iter().zip(&wi) {
                    let e = m.eval_view(&m.view(h, *black_box(wo)), *black_box(wi));
                    let l = &e.lobes;
                    acc += (l.r[0] + l.trt[0] + l.diffuse[0]) + (l.r[1] + l.trt[1] + l.diffuse[1]);
                }
                acc.reduce_add()
            })
        });
        g.bench_function(format!("{}/eval+pdf", sampling.name()), |b| {
            b.iter(|| {
                let mut acc = f32x8::splat(0.0);
                for (wo, wi) in wo.iter().zip(&wi) {
                    let e = m.eval_view(&m.view(h, *black_box(wo)), *black_box(wi));
                    acc += e.lobes.r[0] + e.lobes.trt[0] + e.lobes.diffuse[0] + e.pdf;
                }
                acc.reduce_add()
            })
        });
        g.bench_function(format!("{}/sample", sampling.name()), |b| {
            b.iter(|| {
                let mut acc = f32x8::splat(0.0);
                for (wo, u) in wo.iter().zip(&u) {
                    let s = m.sample_view(&m.view(h, *black_box(wo)), *black_box(u));
                    acc += s.eval.pdf + s.eval.lobes.r[0] + s.wi[0];
                }
                acc.reduce_add()
            })
        });
    }
    g.finish();
}

/// Kajiya-Kay's generic code (`Fibre`) one shading point at a time (`R = f32`, what its `Bsdf` runs) against eight at
/// once (`R = f32x8`), on the inputs of the `kajiya-kay` group: each call takes the view of ωo and then evaluates
/// (f per lobe and the pdf, what a light sample needs) or samples, as the scalar `eval`, `pdf` and `sample` do.
fn bench_kajiya_kay_lanes(c: &mut Criterion, kk: &KajiyaKay, x: &Inputs) {
    const L: usize = fibre::LANES;
    let pack = |w: &[Vec3]| fibre::directions(w.try_into().unwrap());
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

/// ISHair through its generic code (`Fibre`), view included, on the same 1024 (ωo, ωi, ξ) as `ishair-uniform`: one
/// shading point at a time (`R = f32`, what its `Bsdf` runs) against eight at once (`R = f32x8`). Eval gives f per
/// lobe and the pdf together; sample gives ωi with f and the pdf there.
fn bench_ishair_lanes(c: &mut Criterion, m: &IsHair, x: &Inputs) {
    let wo8: Vec<[f32x8; 3]> =
        x.wo.chunks_exact(LANES)
            .map(|w| fibre::directions(w.try_into().unwrap()))
            .collect();
    let wi8: Vec<[f32x8; 3]> =
        x.wi.chunks_exact(LANES)
            .map(|w| fibre::directions(w.try_into().unwrap()))
            .collect();
    let u8: Vec<[f32x8; 3]> =
        x.u.chunks_exact(LANES)
            .map(|u| std::array::from_fn(|c| f32x8::new(std::array::from_fn(|k| u[k][c]))))
            .collect();
    let mut g = c.benchmark_group("ishair-lanes");
    g.throughput(Throughput::Elements(BATCH as u64));
    g.bench_function("eval one at a time", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for k in 0..BATCH {
                let v = m.view(0.0f32, black_box(x.wo[k]).to_array());
                let e = m.eval_view(&v, black_box(x.wi[k]).to_array());
                acc += e.lobes.r[0] + e.lobes.tt[0] + e.lobes.trt[0] + e.lobes.glint[0] + e.pdf;
            }
            acc
        })
    });
    g.bench_function("eval eight at once", |b| {
        b.iter(|| {
            let mut acc = f32x8::splat(0.0);
            for (wo, wi) in wo8.iter().zip(&wi8) {
                let v = m.view(f32x8::splat(0.0), *black_box(wo));
                let e = m.eval_view(&v, *black_box(wi));
                acc += e.lobes.r[0] + e.lobes.tt[0] + e.lobes.trt[0] + e.lobes.glint[0] + e.pdf;
            }
            acc.reduce_add()
        })
    });
    g.bench_function("sample one at a time", |b| {
        b.iter(|| {
            let mut acc = 0.0f32;
            for k in 0..BATCH {
                let v = m.view(0.0f32, black_box(x.wo[k]).to_array());
                let s = m.sample_view(&v, black_box(x.u[k]));
                acc += s.wi[0] + s.eval.lobes.r[0] + s.eval.pdf;
            }
            acc
        })
    });
    g.bench_function("sample eight at once", |b| {
        b.iter(|| {
            let mut acc = f32x8::splat(0.0);
            for (wo, u) in wo8.iter().zip(&u8) {
                let v = m.view(f32x8::splat(0.0), *black_box(wo));
                let s = m.sample_view(&v, *black_box(u));
                acc += s.wi[0] + s.eval.lobes.r[0] + s.eval.pdf;
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
