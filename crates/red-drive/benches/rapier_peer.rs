//! The peer figure's scene, rebuilt with a full rapier2d pipeline so that
//! `drive_step` can be compared with it on the same machine in the same
//! session: a dynamic box car (velocity set each step as a driver would),
//! 5 fixed box obstacles (passed, not hit), 4 fixed walls, zero gravity, one 20 Hz physics
//! step and 20 rays fanned over the front per step.
//!
//! `cargo bench -p red-drive --features rapier-peer --bench rapier_peer`

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rapier2d::prelude::*;
use std::hint::black_box;

struct Scene {
    world: PhysicsWorld,
    car: RigidBodyHandle,
    angles: Vec<f32>,
    t: usize,
}

fn scene() -> Scene {
    let mut world = PhysicsWorld {
        gravity: Vector::ZERO,
        ..PhysicsWorld::default()
    };
    world.integration_parameters.dt = 0.05;
    for (x, y, hx, hy) in [
        (500.0, 6.0, 520.0, 0.5),
        (500.0, -6.0, 520.0, 0.5),
        (-20.0, 0.0, 0.5, 6.5),
        (1020.0, 0.0, 0.5, 6.5),
    ] {
        world.insert(
            RigidBodyBuilder::fixed().translation(Vector::new(x, y)),
            ColliderBuilder::cuboid(hx, hy),
        );
    }
    for k in 0..5 {
        // Obstacles in the middle and left lanes; the car keeps the right one.
        let lane = [0.0f32, 3.5][k % 2];
        world.insert(
            RigidBodyBuilder::fixed().translation(Vector::new(60.0 + 40.0 * k as f32, lane)),
            ColliderBuilder::cuboid(2.25, 0.9),
        );
    }
    let (car, _) = world.insert(
        RigidBodyBuilder::dynamic().translation(Vector::new(0.0, -3.5)),
        ColliderBuilder::cuboid(2.25, 0.9),
    );
    let angles = (0..20)
        .map(|i| {
            let u = -1.0 + 2.0 * i as f32 / 19.0;
            std::f32::consts::FRAC_PI_2 * u
        })
        .collect();
    Scene {
        world,
        car,
        angles,
        t: 0,
    }
}

fn bench_rapier(c: &mut Criterion) {
    let mut s = scene();
    let mut group = c.benchmark_group("rapier2d_peer");
    group.throughput(Throughput::Elements(1));
    group.bench_function("pipeline_step_20_rays", |b| {
        b.iter(|| {
            s.t += 1;
            // Restart the drive every 700 steps (973 m), before the end wall.
            if s.t.is_multiple_of(700) {
                let body = &mut s.world.bodies[s.car];
                body.set_translation(Vector::new(0.0, -3.5), true);
                body.set_rotation(Rotation::new(0.0), true);
            }
            let body = &mut s.world.bodies[s.car];
            let heading = body.rotation().angle();
            let (sn, cs) = heading.sin_cos();
            body.set_linvel(Vector::new(cs, sn) * 27.8, true);
            body.set_angvel(0.02 * (s.t as f32 * 0.05).sin(), true);
            s.world.step();
            let pos = s.world.bodies[s.car].translation();
            let heading = s.world.bodies[s.car].rotation().angle();
            let filter = QueryFilter::default().exclude_rigid_body(s.car);
            let mut sum = 0.0;
            for a in &s.angles {
                let (sn, cs) = (heading + a).sin_cos();
                let ray = Ray::new(pos, Vector::new(cs, sn));
                if let Some((_, toi)) = s.world.cast_ray(&ray, 100.0, true, filter) {
                    sum += toi;
                }
            }
            black_box(sum)
        })
    });
    group.finish();
}

criterion_group!(benches, bench_rapier);
criterion_main!(benches);
