//! Physics speed: a free peg held by the validation impedance, inserted from 2 mm partial
//! insertion in the tightest hole (0.1 mm clearance) at 20 mm/s, either centred or pushed 1 mm
//! sideways so that it slides down along a wall in contact all the way (the costly case). One
//! element is one 1 ms physics step with its controller update; criterion's throughput is the
//! steps per second on one core.

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Isometry3;
use pegtwin::selfcheck::free_peg::{FreePegGains, FreePegRig};
use pegtwin::twin::geometry::{Builtin, build_builtin};
use pegtwin::twin::physics::PhysicsParams;

const STEPS: u64 = 500;

fn free_peg_insertion(c: &mut Criterion) {
    let mut group = c.benchmark_group("free_peg_0.1mm");
    group.sample_size(10);
    group.throughput(Throughput::Elements(STEPS));
    for builtin in Builtin::ALL {
        let pair = build_builtin(builtin, 0.1e-3).expect("built-in builds");
        let params = PhysicsParams::default();
        let start = Isometry3::translation(0.0, 0.0, -2e-3);
        for (scenario, push_x) in [("centred", 0.0), ("sliding_on_wall", 1e-3)] {
            group.bench_function(format!("{}/{scenario}", builtin.name()), |b| {
                b.iter_batched(
                    || FreePegRig::new(&pair, &params, &start, FreePegGains::default()),
                    |mut rig| {
                        for i in 0..STEPS {
                            let z = -2e-3 - 0.02 * i as f64 * 1e-3;
                            rig.target = Isometry3::translation(push_x, 0.0, z);
                            rig.step();
                        }
                        rig
                    },
                    BatchSize::LargeInput,
                )
            });
        }
    }
    group.finish();
}

criterion_group!(benches, free_peg_insertion);
criterion_main!(benches);
