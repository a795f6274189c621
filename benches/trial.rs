//! Trial-level speed on one core: one sampling episode of the offline manifold build (20 s of
//! simulated probing, `cross` at 0.5 mm), and one whole online trial with 10 s of observation
//! (observation, registration against a 50 000-pose manifold, retract, align, insert). The
//! manifold is built once in the set-up with the default sampler (about 100 s on 2 cores).

use criterion::{Criterion, criterion_group, criterion_main};
use pegtwin::method::config::TrialConfig;
use pegtwin::method::manifold::build::{SamplerConfig, build, run_episode};
use pegtwin::method::seeds;
use pegtwin::method::trial::run_trial;
use pegtwin::twin::workcell::WorkCellParams;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let pair = pegtwin::twin::geometry::build_builtin(
        pegtwin::twin::geometry::builtin_by_name("cross").unwrap(),
        0.5e-3,
    )
    .unwrap();
    let robot = pegtwin::twin::robot::urdf::iiwa14().unwrap();
    let params = WorkCellParams::default();
    let sampler = SamplerConfig::default();
    let manifold = build(&pair, &robot, &params, &sampler, 50_000, 1, &|| ())
        .unwrap()
        .manifold;
    let one_core = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut group = c.benchmark_group("one_core");
    group.sample_size(10);
    group.bench_function("sampling_episode_20s_cross_0.5mm", |b| {
        b.iter(|| {
            one_core.install(|| {
                let episode = run_episode(&pair, &robot, &params, &sampler, seeds::episode(1, 0));
                black_box(episode.unwrap().poses.len())
            })
        })
    });
    let config = TrialConfig::default();
    group.bench_function("trial_tobs_10s_cross_0.5mm", |b| {
        b.iter(|| {
            one_core.install(|| {
                let trial = run_trial(&pair, &robot, &params, &config, Some(&manifold), 3, None);
                black_box(trial.unwrap().success)
            })
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
