//! The CPU mirror of the GPU object buffer, and the per-frame deltas that keep the two
//! equal.
//!
//! Objects are identified by a caller-chosen [`ObjectKey`] (the Bevy plugin uses
//! `Entity::to_bits`). Each live object owns a *slot*: its record's index in the buffer.
//! Freed slots are reused lowest first, so the live range stays compact. Every change
//! marks its slot; [`ObjectTable::take_deltas`] returns each marked slot once, in slot
//! order, with its current record (a removed object's slot gets
//! [`ObjectRecord::EMPTY`]), so:
//!
//! - a frame without changes produces no writes (0 bytes);
//! - `k` changed objects produce at most `k` writes of [`DeltaWrite::BYTES`] each,
//!   whatever the scene size;
//! - re-submitting an unchanged record is not a change.
//!
//! The GPU applies the writes in a compute pass (`shaders/df/apply_deltas.wgsl`);
//! [`apply`] is its CPU reference.

use crate::object::{ObjectRecord, RECORD_BYTES, RECORD_WORDS};
use std::collections::{BTreeSet, HashMap};

/// Caller-chosen identity of an object.
pub type ObjectKey = u64;

/// One slot write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeltaWrite {
    /// Slot in the object buffer.
    pub slot: u32,
    /// The record to store there.
    pub record: ObjectRecord,
}

impl DeltaWrite {
    /// Bytes uploaded per write: the slot index and the record.
    pub const BYTES: usize = 4 + RECORD_BYTES;
    /// Words per write in the upload buffer (`shaders/df/apply_deltas.wgsl`).
    pub const WORDS: usize = 1 + RECORD_WORDS;
}

/// A frame's changes.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Deltas {
    /// Slot writes in increasing slot order, each slot at most once.
    pub writes: Vec<DeltaWrite>,
    /// Slots the buffer must hold (one past the highest slot ever used).
    pub slot_count: u32,
}

impl Deltas {
    /// Upload size of the writes, bytes.
    pub fn bytes(&self) -> usize {
        self.writes.len() * DeltaWrite::BYTES
    }

    /// Everything the delta pass needs, split into dispatches that each bind at most
    /// `writes_per_chunk` writes (see [`writes_per_chunk`]): the writes buffer's bytes,
    /// one `DeltaParams` uniform per chunk ([`DELTA_PARAMS_STRIDE`] bytes apart) and
    /// each chunk's range and workgroups.
    pub fn upload(&self, writes_per_chunk: u32) -> DeltaUpload {
        let per_chunk = writes_per_chunk.max(64) / 64 * 64;
        let total = self.writes.len() as u32;
        let mut chunks = Vec::new();
        let mut params = Vec::new();
        let mut first = 0;
        while first < total {
            let count = (total - first).min(per_chunk);
            let (groups, groups_x) = crate::cull::grid_64(count);
            let mut p = [0u8; DELTA_PARAMS_STRIDE as usize];
            p[..4].copy_from_slice(&count.to_le_bytes());
            p[4..8].copy_from_slice(&groups_x.to_le_bytes());
            params.extend_from_slice(&p);
            chunks.push(DeltaChunk {
                first,
                count,
                groups,
            });
            first += count;
        }
        DeltaUpload {
            writes: self
                .to_words()
                .iter()
                .flat_map(|w| w.to_le_bytes())
                .collect(),
            params,
            chunks,
        }
    }

    /// The writes as the upload buffer's words: per write, the slot then the record.
    pub fn to_words(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.writes.len() * DeltaWrite::WORDS);
        for w in &self.writes {
            out.push(w.slot);
            out.extend_from_slice(&w.record.0);
        }
        out
    }
}

/// Bytes between two chunks' `DeltaParams` in the params buffer (wgpu's largest
/// required uniform-offset alignment).
pub const DELTA_PARAMS_STRIDE: u64 = 256;

/// The most writes one dispatch of the delta pass binds when a storage binding may hold
/// `max_binding_bytes` (the device's `max_storage_buffer_binding_size`): a multiple of
/// 64, so every chunk starts on a 256-byte boundary (64 writes are 33 × 256 bytes).
pub fn writes_per_chunk(max_binding_bytes: u64) -> u32 {
    let n = max_binding_bytes / DeltaWrite::BYTES as u64 / 64 * 64;
    n.clamp(64, u64::from(u32::MAX) / 64 * 64) as u32
}

/// A frame's delta upload ([`Deltas::upload`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeltaUpload {
    /// All writes, little-endian words, back to back.
    pub writes: Vec<u8>,
    /// One `DeltaParams` uniform (write count, dispatch row width, padding) per chunk,
    /// [`DELTA_PARAMS_STRIDE`] bytes apart.
    pub params: Vec<u8>,
    /// The dispatches, in order.
    pub chunks: Vec<DeltaChunk>,
}

/// One dispatch of the delta pass: it binds writes `first..first + count` (byte offset
/// `first × DeltaWrite::BYTES`, 256-byte aligned) and params `index ×
/// DELTA_PARAMS_STRIDE`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeltaChunk {
    /// Index of its first write.
    pub first: u32,
    /// Writes in it.
    pub count: u32,
    /// Workgroups of 64 to dispatch.
    pub groups: [u32; 3],
}

/// The mirror.
#[derive(Clone, Debug, Default)]
pub struct ObjectTable {
    records: Vec<ObjectRecord>,
    keys: Vec<Option<ObjectKey>>,
    slot_of: HashMap<ObjectKey, u32>,
    free: BTreeSet<u32>,
    dirty: Vec<bool>,
    dirty_slots: Vec<u32>,
}

impl ObjectTable {
    /// An empty table.
    pub fn new() -> ObjectTable {
        ObjectTable::default()
    }

    /// Live objects.
    pub fn len(&self) -> usize {
        self.slot_of.len()
    }

    /// Whether no object is live.
    pub fn is_empty(&self) -> bool {
        self.slot_of.is_empty()
    }

    /// Slots the buffer must hold.
    pub fn slot_count(&self) -> u32 {
        self.records.len() as u32
    }

    /// The mirror of the buffer, by slot (free slots hold [`ObjectRecord::EMPTY`]).
    pub fn records(&self) -> &[ObjectRecord] {
        &self.records
    }

    /// The slot of a live object.
    pub fn slot(&self, key: ObjectKey) -> Option<u32> {
        self.slot_of.get(&key).copied()
    }

    fn mark(&mut self, slot: u32) {
        if !self.dirty[slot as usize] {
            self.dirty[slot as usize] = true;
            self.dirty_slots.push(slot);
        }
    }

    /// Adds an object or updates its record; returns its slot. Unchanged records are
    /// not marked.
    pub fn upsert(&mut self, key: ObjectKey, record: ObjectRecord) -> u32 {
        if let Some(&slot) = self.slot_of.get(&key) {
            if self.records[slot as usize] != record {
                self.records[slot as usize] = record;
                self.mark(slot);
            }
            return slot;
        }
        let slot = match self.free.pop_first() {
            Some(slot) => slot,
            None => {
                self.records.push(ObjectRecord::EMPTY);
                self.keys.push(None);
                self.dirty.push(false);
                self.records.len() as u32 - 1
            }
        };
        self.records[slot as usize] = record;
        self.keys[slot as usize] = Some(key);
        self.slot_of.insert(key, slot);
        self.mark(slot);
        slot
    }

    /// Removes an object; its slot is cleared and becomes free. `false` if unknown.
    pub fn remove(&mut self, key: ObjectKey) -> bool {
        let Some(slot) = self.slot_of.remove(&key) else {
            return false;
        };
        self.records[slot as usize] = ObjectRecord::EMPTY;
        self.keys[slot as usize] = None;
        self.free.insert(slot);
        self.mark(slot);
        true
    }

    /// The writes that bring the GPU buffer from the last taken state to the current
    /// one, and clears the marks.
    pub fn take_deltas(&mut self) -> Deltas {
        let mut slots = std::mem::take(&mut self.dirty_slots);
        slots.sort_unstable();
        let writes = slots
            .into_iter()
            .map(|slot| {
                self.dirty[slot as usize] = false;
                DeltaWrite {
                    slot,
                    record: self.records[slot as usize],
                }
            })
            .collect();
        Deltas {
            writes,
            slot_count: self.slot_count(),
        }
    }
}

/// The CPU reference of the GPU delta pass: grows `buffer` to `deltas.slot_count`
/// (new slots empty) and applies the writes.
pub fn apply(buffer: &mut Vec<ObjectRecord>, deltas: &Deltas) {
    if buffer.len() < deltas.slot_count as usize {
        buffer.resize(deltas.slot_count as usize, ObjectRecord::EMPTY);
    }
    for w in &deltas.writes {
        buffer[w.slot as usize] = w.record;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(seed: u32) -> ObjectRecord {
        let mut r = ObjectRecord([0; RECORD_WORDS]);
        for (i, w) in r.0.iter_mut().enumerate() {
            *w = seed.wrapping_mul(2_654_435_761).wrapping_add(i as u32);
        }
        r
    }

    /// Random churn: the buffer rebuilt from deltas always equals the mirror, static
    /// frames send nothing, writes are bounded by the frame's changes, slots are reused.
    #[test]
    fn deltas_reproduce_the_mirror_under_churn() {
        let mut table = ObjectTable::new();
        let mut gpu: Vec<ObjectRecord> = Vec::new();
        let mut live: Vec<ObjectKey> = Vec::new();
        let mut next_key = 0u64;
        let mut s = 11u64;
        let mut rand = |m: u64| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (s >> 33) % m
        };
        let mut ops = 0;
        for frame in 0..500 {
            let changes = if frame % 7 == 0 { 0 } else { rand(60) };
            let mut touched = std::collections::HashSet::new();
            for _ in 0..changes {
                ops += 1;
                match rand(4) {
                    0 | 1 => {
                        let k = next_key;
                        next_key += 1;
                        table.upsert(k, record(rand(1 << 30) as u32));
                        live.push(k);
                        touched.insert(k);
                    }
                    2 if !live.is_empty() => {
                        let k = live.swap_remove(rand(live.len() as u64) as usize);
                        assert!(table.remove(k));
                        touched.insert(k);
                    }
                    _ if !live.is_empty() => {
                        let k = live[rand(live.len() as u64) as usize];
                        table.upsert(k, record(rand(1 << 30) as u32));
                        touched.insert(k);
                    }
                    _ => {}
                }
            }
            let deltas = table.take_deltas();
            assert!(deltas.writes.len() <= touched.len(), "frame {frame}");
            assert!(deltas.writes.windows(2).all(|w| w[0].slot < w[1].slot));
            if changes == 0 {
                assert_eq!(deltas.bytes(), 0, "static frame {frame}");
            }
            apply(&mut gpu, &deltas);
            assert_eq!(gpu.as_slice(), table.records(), "frame {frame}");
            assert_eq!(table.len(), live.len());
        }
        assert!(ops > 10_000, "{ops} operations");
        // Slots are reused: the buffer is not much larger than the peak live count.
        assert!(
            table.slot_count() as usize <= next_key as usize / 2,
            "{}",
            table.slot_count()
        );
    }

    /// Large uploads are split: every write in exactly one chunk, in order, each chunk
    /// within the binding limit and 256-byte aligned; applying the chunks one by one
    /// (as the GPU does) gives the same buffer.
    #[test]
    fn uploads_split_into_aligned_chunks_within_the_binding_limit() {
        let mut table = ObjectTable::new();
        for k in 0..1000 {
            table.upsert(k, record(k as u32));
        }
        let deltas = table.take_deltas();
        for max_binding in [64 * 132, 100_000, 132 * 1000, 1 << 27] {
            let per_chunk = writes_per_chunk(max_binding);
            assert_eq!(per_chunk % 64, 0);
            let upload = deltas.upload(per_chunk);
            assert_eq!(upload.writes.len(), deltas.bytes());
            assert_eq!(
                upload.params.len() as u64,
                upload.chunks.len() as u64 * DELTA_PARAMS_STRIDE
            );
            let mut next = 0;
            let mut gpu = vec![ObjectRecord::EMPTY; deltas.slot_count as usize];
            for (i, c) in upload.chunks.iter().enumerate() {
                assert_eq!(c.first, next, "{max_binding}");
                let offset = c.first as u64 * DeltaWrite::BYTES as u64;
                let bytes = c.count as u64 * DeltaWrite::BYTES as u64;
                assert_eq!(offset % 256, 0, "{max_binding}: chunk {i}");
                assert!(bytes <= max_binding.max(64 * 132), "{max_binding}: {bytes}");
                let p = &upload.params[i * 256..i * 256 + 8];
                assert_eq!(u32::from_le_bytes(p[..4].try_into().unwrap()), c.count);
                // The chunk's writes, as the pass reads them from its binding.
                let words: Vec<u32> = upload.writes[offset as usize..(offset + bytes) as usize]
                    .chunks_exact(4)
                    .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
                    .collect();
                for w in words.chunks_exact(DeltaWrite::WORDS) {
                    gpu[w[0] as usize] = ObjectRecord(w[1..].try_into().unwrap());
                }
                next += c.count;
            }
            assert_eq!(next, 1000);
            assert_eq!(gpu.as_slice(), table.records(), "{max_binding}");
        }
        assert_eq!(writes_per_chunk(1 << 27), 1_016_768);
        assert!(Deltas::default().upload(64).chunks.is_empty());
    }

    #[test]
    fn unchanged_records_and_unknown_keys_cost_nothing() {
        let mut table = ObjectTable::new();
        table.upsert(1, record(5));
        assert_eq!(table.take_deltas().writes.len(), 1);
        table.upsert(1, record(5));
        assert!(!table.remove(99));
        assert_eq!(
            table.take_deltas(),
            Deltas {
                writes: vec![],
                slot_count: 1
            }
        );
        // Add then remove within one frame: one write, of the empty record.
        table.upsert(2, record(6));
        table.remove(2);
        let d = table.take_deltas();
        assert_eq!(
            d.writes,
            vec![DeltaWrite {
                slot: 1,
                record: ObjectRecord::EMPTY
            }]
        );
        // The freed slot is the next one handed out.
        assert_eq!(table.upsert(3, record(7)), 1);
        assert_eq!(d.to_words().len(), DeltaWrite::WORDS);
    }
}
