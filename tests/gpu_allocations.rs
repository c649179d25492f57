//! Penumbra pools its GPU resources: once the `df_shadows` example's scene is steady
//! (with `--lights 4`: the sun, the lamp and two small lamps; casters and lights moving
//! every frame), a frame creates no buffer, texture or bind group
//! (`PenumbraGpuAllocations`). Before pooling, the shadow passes created about ten
//! buffers and several bind groups per light, per view, per frame.

#[path = "../examples/df_shadows.rs"]
#[allow(dead_code, reason = "the example's main is not used here")]
mod df_shadows;

use bevy::prelude::*;
use penumbra::df::{GpuAllocationCounts, PenumbraGpuAllocations};
use penumbra_test::{HeadlessRender, gpu_or_skip};

#[derive(Resource, Default)]
struct Log(Vec<GpuAllocationCounts>);

fn record(allocations: Res<PenumbraGpuAllocations>, mut log: ResMut<Log>) {
    log.0.push(allocations.counts());
}

#[test]
fn steady_frames_create_no_gpu_resources() {
    if !gpu_or_skip("steady_frames_create_no_gpu_resources") {
        return;
    }
    const FRAMES: u32 = 12;
    let render = HeadlessRender::new(128, 128)
        .frames(FRAMES)
        .warm_up(df_shadows::casters_ready);
    let mut app = render.app();
    let options = df_shadows::Options::parse(["--lights".to_string(), "4".to_string()]).unwrap();
    app.insert_resource(options)
        .init_resource::<Log>()
        .add_systems(Last, record);
    df_shadows::add_scene(&mut app);
    let (capture, app) = render.run_keeping_app(app).unwrap();
    let log = &app.world().resource::<Log>().0;
    // The last frames: the counted ones and the readback's, the first few left out (the
    // render world runs a frame behind; views and masks appear in the first frames).
    let steady = &log[log.len() - FRAMES as usize + 4..];
    let per_frame: Vec<GpuAllocationCounts> = steady.windows(2).map(|w| w[1] - w[0]).collect();
    let total = *steady.last().unwrap() - steady[0];
    let mean_ms = capture.frame_times[1..]
        .iter()
        .map(|d| d.as_secs_f64() * 1e3)
        .sum::<f64>()
        / (capture.frame_times.len() - 1) as f64;
    println!(
        "{} steady frames: {total:?} in all; since startup {:?}; mean frame time {mean_ms:.1} ms",
        per_frame.len(),
        log.last().unwrap()
    );
    assert!(
        log.last().unwrap().buffers > 0,
        "the scene allocated nothing"
    );
    assert_eq!(
        total,
        GpuAllocationCounts::default(),
        "per frame: {per_frame:#?}"
    );
}
