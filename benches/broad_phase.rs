//! Criterion benchmark of the voxel-hash broad phase from 1k to 100k
//! particles: rebuild plus all pairs closer than one grid spacing, on a
//! gently crumpled sheet. Cost should grow linearly.
//!
//! Run: `cargo bench -p cloth-benches --bench broad_phase`

use cloth_collide::{Vec3, VoxelHash};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};

fn sheet(n_side: usize, spacing: f64) -> Vec<Vec3> {
    (0..n_side * n_side)
        .map(|k| {
            let (i, j) = ((k % n_side) as f64, (k / n_side) as f64);
            Vec3::new(i * spacing, j * spacing, 0.3 * spacing * ((i * 0.37).sin() + (j * 0.21).cos()))
        })
        .collect()
}

fn broad_phase(c: &mut Criterion) {
    let mut group = c.benchmark_group("voxel_hash_rebuild_and_pairs");
    let spacing = 0.01;
    for n_side in [32, 100, 200, 317] {
        let points = sheet(n_side, spacing);
        let mut hash = VoxelHash::new(spacing).expect("positive voxel");
        group.throughput(Throughput::Elements(points.len() as u64));
        group.bench_with_input(BenchmarkId::from_parameter(points.len()), &points, |b, pts| {
            b.iter(|| {
                hash.insert_points(pts).expect("finite points");
                hash.pairs_within(spacing, |_, _| false).len()
            })
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = broad_phase
}
criterion_main!(benches);
