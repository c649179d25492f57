//! Object-buffer updates: 100,000 casters with 1 % moving per frame, sent as deltas
//! versus re-uploading the whole buffer — bytes and CPU time of the work the Bevy
//! plugin does per frame (encode the changed records, update the mirror, take the
//! deltas, serialise the upload), both measured here.
//!
//! `cargo bench -p penumbra_df_core --bench object_buffer`

#![allow(missing_docs, reason = "criterion_group! generates undocumented items")]

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{Affine3A, Quat, Vec3};
use penumbra_df_core::object::{CasterShape, ObjectDesc, RECORD_WORDS, encode, flags};
use penumbra_df_core::table::ObjectTable;
use std::hint::black_box;

const OBJECTS: usize = 100_000;
const MOVING: usize = OBJECTS / 100;

fn desc(i: usize, frame: u32) -> ObjectDesc {
    let a = i as f32 * 0.618;
    ObjectDesc {
        world_from_local: Affine3A::from_scale_rotation_translation(
            Vec3::new(1.0, 1.0 + (i % 3) as f32 * 0.5, 1.0),
            Quat::from_rotation_y(a),
            Vec3::new((i % 300) as f32, frame as f32 * 0.01, (i / 300) as f32),
        ),
        shape: CasterShape::Sphere { radius: 0.5 },
        flags: flags::VISIBLE | flags::CASTS_SHADOWS,
    }
}

fn scene() -> ObjectTable {
    let mut table = ObjectTable::new();
    for i in 0..OBJECTS {
        table.upsert(i as u64, encode(&desc(i, 0)).unwrap());
    }
    table.take_deltas();
    table
}

/// One frame with deltas: returns the bytes uploaded.
fn delta_frame(table: &mut ObjectTable, frame: u32) -> usize {
    for k in 0..MOVING {
        let i = (k * 7919 + frame as usize * 131) % OBJECTS;
        table.upsert(i as u64, encode(&desc(i, frame)).unwrap());
    }
    let deltas = table.take_deltas();
    let words = deltas.to_words();
    black_box(&words);
    words.len() * 4
}

/// One frame re-uploading everything: returns the bytes uploaded.
fn full_frame(frame: u32) -> usize {
    let mut words = Vec::with_capacity(OBJECTS * RECORD_WORDS);
    for i in 0..OBJECTS {
        words.extend_from_slice(&encode(&desc(i, frame)).unwrap().0);
    }
    black_box(&words);
    words.len() * 4
}

fn object_buffer(c: &mut Criterion) {
    let mut table = scene();
    let delta_bytes = delta_frame(&mut table, 1);
    let full_bytes = full_frame(1);
    let static_bytes = table.take_deltas().bytes();
    let time = |f: &mut dyn FnMut()| {
        let t = std::time::Instant::now();
        for _ in 0..20 {
            f();
        }
        t.elapsed().as_secs_f64() / 20.0
    };
    let mut frame = 2;
    let t_delta = time(&mut || {
        delta_frame(&mut table, frame);
        frame += 1;
    });
    let t_full = time(&mut || {
        full_frame(frame);
    });
    println!("\n{OBJECTS} casters, {MOVING} moving per frame (mean of 20 frames):");
    println!("| | bytes per frame | CPU time per frame |");
    println!("|---|---|---|");
    println!("| deltas | {delta_bytes} | {:.3} ms |", t_delta * 1e3);
    println!("| full re-upload | {full_bytes} | {:.3} ms |", t_full * 1e3);
    println!("| static frame | {static_bytes} | - |");
    println!(
        "ratio: {:.1}x fewer bytes, {:.1}x less CPU time\n",
        full_bytes as f64 / delta_bytes as f64,
        t_full / t_delta
    );

    let mut group = c.benchmark_group("object_buffer_100k");
    group.sample_size(20);
    let mut frame = 1000;
    group.bench_function("deltas_1_percent", |b| {
        b.iter(|| {
            frame += 1;
            delta_frame(&mut table, frame)
        });
    });
    group.bench_function("full_reupload", |b| b.iter(|| full_frame(7)));
    group.finish();
}

criterion_group!(benches, object_buffer);
criterion_main!(benches);
