//! Replays the committed fuzz corpus and every input that once failed through the
//! targets, as ordinary tests (no fuzzer, no instrumentation): each must return without
//! a panic — not even one the code catches itself, which `panic = "abort"` would make an
//! abort.

use penumbra_fuzz::{Target, crate_dir, engine::read_corpus};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// One replay at a time: the panic count is global.
static LOCK: Mutex<()> = Mutex::new(());
static PANICS: AtomicUsize = AtomicUsize::new(0);

fn replay(target: Target) {
    let _one_at_a_time = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        PANICS.fetch_add(1, Ordering::Relaxed);
        default(info);
    }));
    PANICS.store(0, Ordering::Relaxed);
    let mut runs = 0;
    for folder in ["corpus", "regressions"] {
        for data in read_corpus(&crate_dir().join(folder).join(target.name())) {
            target.run(&data);
            runs += 1;
        }
    }
    for seed in target.seeds() {
        target.run(&seed);
        runs += 1;
    }
    let _ = std::panic::take_hook();
    eprintln!("{}: {runs} inputs replayed", target.name());
    assert_eq!(
        PANICS.load(Ordering::Relaxed),
        0,
        "{}: panics (caught or not) while replaying",
        target.name()
    );
}

#[test]
fn psdf_inputs_replay() {
    replay(Target::Psdf);
}

#[test]
fn obj_inputs_replay() {
    replay(Target::Obj);
}

#[test]
fn gltf_inputs_replay() {
    replay(Target::Gltf);
}

#[test]
fn hair_inputs_replay() {
    replay(Target::Hair);
}

#[test]
fn ribbon_inputs_replay() {
    replay(Target::Ribbons);
}

#[test]
fn tessellation_inputs_replay() {
    replay(Target::Tessellation);
}

/// The seeds are valid inputs: a target that rejected them would search from nothing.
#[test]
fn seeds_are_accepted() {
    use penumbra_sdf::{format, gltf_input, obj};
    for seed in Target::Psdf.seeds() {
        format::from_bytes(&seed).expect("psdf seed");
    }
    for seed in Target::Obj.seeds() {
        obj::parse_obj(std::str::from_utf8(&seed).expect("text")).expect("obj seed");
    }
    for seed in Target::Gltf.seeds() {
        let (mesh, _) = gltf_input::load_gltf(&seed, None, &gltf_input::GltfSelection::Scene)
            .expect("gltf seed");
        assert_eq!(mesh.triangles.len(), 1);
    }
    for seed in Target::Hair.seeds() {
        let strands = penumbra_cinematic_core::hair::strands::parse_hair(
            std::str::from_utf8(&seed).expect("text"),
        )
        .expect("hair seed");
        assert_eq!(strands.len(), 2);
    }
}
