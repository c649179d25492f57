// Applies a frame's object-buffer deltas: each write is a slot index followed by the
// slot's 32-word record (`penumbra_df_core::table::Deltas::to_words`). The CPU
// reference is `penumbra_df_core::table::apply`.
#define_import_path penumbra::df::apply_deltas

struct DeltaParams {
    // Writes in `writes`.
    count: u32,
    // Workgroups per row of the 2D dispatch (large counts exceed 65535 groups in x).
    groups_x: u32,
    _pad0: u32,
    _pad1: u32,
}

const RECORD_WORDS: u32 = 32u;
const WRITE_WORDS: u32 = 33u;

@group(0) @binding(0) var<storage, read_write> objects: array<u32>;
@group(0) @binding(1) var<storage, read> writes: array<u32>;
@group(0) @binding(2) var<uniform> params: DeltaParams;

@compute @workgroup_size(64)
fn apply_deltas(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x + id.y * params.groups_x * 64u;
    if i >= params.count {
        return;
    }
    let base = i * WRITE_WORDS;
    let slot = writes[base];
    for (var k = 0u; k < RECORD_WORDS; k += 1u) {
        objects[slot * RECORD_WORDS + k] = writes[base + 1u + k];
    }
}
