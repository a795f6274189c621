//! Physics speed of the robot cell: the iiwa 14 multibody under 1 kHz Cartesian impedance, the
//! `cross` peg (and the `gear`, the built-in with the most convex pieces) 5 mm inside its hole at
//! 0.1 mm clearance, probing the walls with a small circle in x, y and a rocking in roll and pitch
//! (as the observation phase does; the scenes of `pegtwin bench`, `src/campaign/bench.rs`).
//! Each scene runs with the joint-space contact solve (`twin::physics::joint_contacts`, the
//! default) and with rapier's contacts (names ending `_rapier`).
//! Throughput is physics steps (1 ms each) per second on one core.

use criterion::measurement::WallTime;
use criterion::{
    BatchSize, BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main,
};
use pegtwin::campaign::bench::{arm_scene, probe};
use pegtwin::twin::physics::ArmContacts;
use std::hint::black_box;

const STEPS: usize = 2000;

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("arm_cell");
    group.sample_size(10);
    group.throughput(Throughput::Elements(STEPS as u64));
    for contacts in [ArmContacts::JointSpace, ArmContacts::Rapier] {
        for geometry in ["cross", "gear"] {
            bench_geometry(&mut group, geometry, contacts);
        }
    }
    group.finish();
}

fn bench_geometry(group: &mut BenchmarkGroup<'_, WallTime>, geometry: &str, contacts: ArmContacts) {
    let suffix = match contacts {
        ArmContacts::JointSpace => "",
        ArmContacts::Rapier => "_rapier",
    };
    group.bench_function(format!("{geometry}_0.1mm_probing_steps{suffix}"), |b| {
        b.iter_batched(
            || arm_scene(geometry, contacts).unwrap(),
            |(mut cell, start)| {
                probe(&mut cell, &start, STEPS);
                black_box(cell.truth().tcp_pose())
            },
            BatchSize::LargeInput,
        )
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
