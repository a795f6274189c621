//! Registration speed (issue 4's targets): a 100 000-point analytic `cross` manifold (0.5 mm
//! clearance), 1000 noisy observations through a 5 mm / 5 deg offset; building the index and the
//! normals; nearest-neighbour queries with and without the spread-equalising rotation; and a full
//! registration of 16 restarts x 50 iterations (tolerance 0, so all 50 run) on the machine's
//! threads, with each solver.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use pegtwin::method::manifold::synthetic::SyntheticPair;
use pegtwin::method::manifold::{Manifold, ManifoldMeta, ScaledIndex, UNITS};
use pegtwin::method::register::{RegistrationConfig, Solver, register};
use pegtwin::pose::{Pose6, PoseMetric};
use std::hint::black_box;

const MANIFOLD_POINTS: usize = 100_000;
const OBSERVATIONS: usize = 1000;

fn meta(pair: &SyntheticPair) -> ManifoldMeta {
    ManifoldMeta {
        geometry: pair.name.clone(),
        clearance_m: Some(pair.clearance_m),
        units: UNITS.into(),
        metric: PoseMetric::default(),
        normal_k: pegtwin::method::manifold::DEFAULT_NORMAL_K,
        source: "benchmark".into(),
        seed: Some(1),
    }
}

fn registration(c: &mut Criterion) {
    let pair = SyntheticPair::cross(0.03, 0.01, 0.5e-3);
    let points = pair.sample_contacts(MANIFOLD_POINTS, [0.001, 0.015], 1);
    let truth = Pose6([0.6, 0.05, 0.2, 0.0, 0.0, 0.3]);
    let obs = pair.observe(
        &truth,
        OBSERVATIONS,
        [0.002, 0.008],
        (5e-6, 0.005f64.to_radians()),
        2,
    );
    let init = truth.compose(&Pose6([0.004, -0.003, 0.005, 0.07, -0.05, 0.08]));

    let mut group = c.benchmark_group("manifold_100k");
    group.sample_size(10);
    group.bench_function("index_and_normals", |b| {
        b.iter(|| Manifold::from_points(black_box(points.clone()), meta(&pair)).unwrap())
    });
    let metric = PoseMetric::default();
    let scaled: Vec<[f64; 6]> = points.iter().map(|p| metric.scaled(p)).collect();
    let queries: Vec<[f64; 6]> = obs
        .iter()
        .map(|o| metric.scaled(&truth.relative(o)))
        .collect();
    group.throughput(Throughput::Elements(queries.len() as u64));
    for (name, index) in [
        ("nearest/spread_equalised", ScaledIndex::new(&scaled)),
        ("nearest/plain_kiddo", ScaledIndex::unrotated(&scaled)),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| queries.iter().map(|q| index.nearest(q).0).sum::<usize>())
        });
    }
    group.finish();

    let manifold = Manifold::from_points(points, meta(&pair)).unwrap();
    let mut group = c.benchmark_group("register_16x50");
    group.sample_size(10);
    for solver in [Solver::Paper, Solver::LeastSquares] {
        let cfg = RegistrationConfig {
            solver,
            restarts: 16,
            iterations: 50,
            tolerance_mm: 0.0,
            ..Default::default()
        };
        group.bench_function(format!("{solver:?}"), |b| {
            b.iter(|| register(&manifold, &obs, &init, &cfg).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, registration);
criterion_main!(benches);
