//! Wavelet transform throughput on hierarchies of about one million vertices (issue "Wavelet
//! transforms", Performance): forward and inverse, per wavelet, in vertices per second.
//!
//! `cargo bench -p subwave --bench wavelet` (criterion's "thrpt" is finest-level vertices per
//! second). The same figures on a mesh file: `subwave wavelet MESH --wavelet W --runs 11`
//! (median and fastest of the in-place transforms, plan time apart). Triangle wavelets run on a torus of 512 triangles refined 6 times (1,050,624
//! vertices) with Loop-smoothed positions; Bertram's B-spline wavelets on a torus of 256 quads
//! refined 6 times (1,048,576 vertices) with bicubic-smoothed positions.

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion, Throughput};
use subwave::generate;
use subwave::hierarchy::Hierarchy;
use subwave::subdivision::refine::Split;
use subwave::subdivision::{subdivide, Scheme, SubdivideOptions};
use subwave::wavelet::bertram::{quad_hierarchy, BSplineWavelet, Degree};
use subwave::wavelet::triangle::TriangleWavelet;
use subwave::wavelet::triangle_int::IntTriangleWavelet;

/// Large buffers in transparent huge pages (fewer first-touch page faults; `subwave::alloc`).
#[global_allocator]
static ALLOC: subwave::alloc::HugePages = subwave::alloc::HugePages;

const LEVELS: u32 = 6;

fn triangles(c: &mut Criterion) {
    let base = generate::torus(1.0, 0.4, 16, 16, true);
    let opts = SubdivideOptions {
        scheme: Scheme::Loop,
        levels: LEVELS,
        ..Default::default()
    };
    let smooth = subdivide(&base, &opts)
        .expect("Loop refines the torus")
        .positions;
    let h = Hierarchy::new(&base, LEVELS, Split::Triangles, Some(smooth)).expect("hierarchy");
    let n = h.positions.len();
    let mut g = c.benchmark_group("triangle_wavelets_1M");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    let butterfly = SubdivideOptions {
        scheme: Scheme::Butterfly,
        ..Default::default()
    };
    let wavelets = [
        ("midpoint", TriangleWavelet::midpoint(&h, false).unwrap()),
        (
            "midpoint-lifted",
            TriangleWavelet::midpoint(&h, true).unwrap(),
        ),
        (
            "butterfly-lifted",
            TriangleWavelet::from_scheme(&h, &butterfly, true).unwrap(),
        ),
        (
            "loop",
            TriangleWavelet::loop_pgc(&h, &SubdivideOptions::default()).unwrap(),
        ),
    ];
    for (name, w) in &wavelets {
        let d = w.decompose(&h.positions).unwrap();
        g.bench_function(BenchmarkId::new("forward", name), |b| {
            b.iter(|| w.decompose(&h.positions).unwrap())
        });
        g.bench_function(BenchmarkId::new("inverse", name), |b| {
            b.iter(|| w.reconstruct(&d).unwrap())
        });
        if *name == "loop" {
            continue;
        }
        // The lifting scheme proper: in place, no allocation (the copy of the input is
        // set-up, outside the timing).
        g.bench_function(BenchmarkId::new("forward-in-place", name), |b| {
            b.iter_batched_ref(
                || h.positions.clone(),
                |data| w.decompose_in_place(data).unwrap(),
                BatchSize::LargeInput,
            )
        });
        let flat = d.to_flat();
        g.bench_function(BenchmarkId::new("inverse-in-place", name), |b| {
            b.iter_batched_ref(
                || flat.clone(),
                |data| w.reconstruct_in_place(data).unwrap(),
                BatchSize::LargeInput,
            )
        });
    }
    // Integer lifted wavelets (lossless mode), on the positions scaled to 2^20.
    let ints: Vec<[i64; 3]> = h
        .positions
        .iter()
        .map(|p| (*p * (1 << 20) as f64).round().to_array().map(|x| x as i64))
        .collect();
    for (name, scheme) in [
        ("midpoint-int", Scheme::Midpoint),
        ("butterfly-int", Scheme::Butterfly),
    ] {
        let opts = SubdivideOptions {
            scheme,
            ..Default::default()
        };
        let w = IntTriangleWavelet::from_scheme(&h, &opts, true).unwrap();
        g.bench_function(BenchmarkId::new("forward-in-place", name), |b| {
            b.iter_batched_ref(
                || ints.clone(),
                |data| w.forward(data).unwrap(),
                BatchSize::LargeInput,
            )
        });
        let mut coeffs = ints.clone();
        w.forward(&mut coeffs).unwrap();
        g.bench_function(BenchmarkId::new("inverse-in-place", name), |b| {
            b.iter_batched_ref(
                || coeffs.clone(),
                |data| w.inverse(data).unwrap(),
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

fn quads(c: &mut Criterion) {
    let base = generate::torus(1.0, 0.4, 16, 16, false);
    let r = quad_hierarchy(&base, LEVELS).expect("quad hierarchy");
    let levels = &r.topologies;
    let fine = BSplineWavelet::new(Degree::Cubic)
        .subdivide(levels, &base.positions)
        .expect("bicubic");
    let n = fine.len();
    let mut g = c.benchmark_group("bspline_wavelets_1M");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    // In place on a buffer filled outside the timing (criterion's batched set-up): the
    // transform of a hierarchy already in memory, as `subwave wavelet --runs N` times it.
    for degree in [Degree::Linear, Degree::Cubic, Degree::Quintic] {
        let w = BSplineWavelet::new(degree);
        g.bench_function(BenchmarkId::new("forward", degree.name()), |b| {
            b.iter_batched_ref(
                || fine.clone(),
                |data| w.analyze(levels, data).unwrap(),
                BatchSize::LargeInput,
            )
        });
        let mut coeffs = fine.clone();
        w.analyze(levels, &mut coeffs).unwrap();
        g.bench_function(BenchmarkId::new("inverse", degree.name()), |b| {
            b.iter_batched_ref(
                || coeffs.clone(),
                |data| w.synthesize(levels, data).unwrap(),
                BatchSize::LargeInput,
            )
        });
        // Integer: coordinates scaled to 2^20 and rounded.
        let ints: Vec<[i64; 3]> = fine
            .iter()
            .map(|p| (*p * (1 << 20) as f64).round().to_array().map(|x| x as i64))
            .collect();
        g.bench_function(BenchmarkId::new("forward-int", degree.name()), |b| {
            b.iter_batched_ref(
                || ints.clone(),
                |data| w.analyze_int(levels, data).unwrap(),
                BatchSize::LargeInput,
            )
        });
        let mut icoeffs = ints.clone();
        w.analyze_int(levels, &mut icoeffs).unwrap();
        g.bench_function(BenchmarkId::new("inverse-int", degree.name()), |b| {
            b.iter_batched_ref(
                || icoeffs.clone(),
                |data| w.synthesize_int(levels, data).unwrap(),
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

criterion_group!(benches, triangles, quads);
criterion_main!(benches);
