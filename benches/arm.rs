//! Physics speed of the robot cell: the iiwa 14 multibody under 1 kHz Cartesian impedance, the
//! `cross` peg (and the `gear`, the built-in with the most convex pieces) 5 mm inside its hole at
//! 0.1 mm clearance, probing the walls with a small circle in x, y and a rocking in roll and pitch
//! (as the observation phase does). Throughput is physics steps (1 ms each) per second on one
//! core.

use criterion::measurement::WallTime;
use criterion::{
    BatchSize, BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main,
};
use pegtwin::twin::cell::{Cell, CellParams, nominal_hole_pose, tcp_in_hole};
use pegtwin::twin::control::ImpedanceGains;
use pegtwin::twin::geometry::{build_builtin, builtin_by_name};
use pegtwin::twin::robot::Iso;
use pegtwin::twin::robot::urdf::iiwa14;
use std::hint::black_box;

const STEPS: usize = 2000;

fn probing_target(start: &Iso, t: f64) -> Iso {
    let w = std::f64::consts::TAU;
    start
        * Iso::translation(0.3e-3 * (w * t).cos(), 0.3e-3 * (w * t).sin(), -1e-3)
        * Iso::rotation(nalgebra::Vector3::new(
            0.5f64.to_radians() * (w * 1.3 * t).sin(),
            0.5f64.to_radians() * (w * 0.7 * t).sin(),
            0.0,
        ))
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("arm_cell");
    group.sample_size(10);
    group.throughput(Throughput::Elements(STEPS as u64));
    for geometry in ["cross", "gear"] {
        bench_geometry(&mut group, geometry);
    }
    group.finish();
}

fn bench_geometry(group: &mut BenchmarkGroup<'_, WallTime>, geometry: &str) {
    let pair = build_builtin(builtin_by_name(geometry).unwrap(), 0.1e-3).unwrap();
    let params = CellParams::default();
    let hole = nominal_hole_pose(&pair, &params);
    let start = tcp_in_hole(&hole, 0.005);
    let gains = ImpedanceGains::uniform(500.0, 20.0, 0.7);
    let make = || {
        let mut cell = Cell::new(
            &pair,
            iiwa14().unwrap(),
            &params,
            Some(hole),
            &start,
            gains.clone(),
            1,
        )
        .unwrap();
        for _ in 0..200 {
            let t = cell.time_s();
            cell.command_pose(probing_target(&start, t));
            cell.step();
        }
        cell
    };
    group.bench_function(format!("{geometry}_0.1mm_probing_steps"), |b| {
        b.iter_batched(
            make,
            |mut cell| {
                for _ in 0..STEPS {
                    let t = cell.time_s();
                    cell.command_pose(probing_target(&start, t));
                    cell.step();
                }
                black_box(cell.truth().tcp_pose())
            },
            BatchSize::LargeInput,
        )
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
