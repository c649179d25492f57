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

    /// Everything the delta pass needs: the writes buffer's bytes, its `DeltaParams`
    /// uniform (`shaders/df/apply_deltas.wgsl`) and the workgroups to dispatch.
    pub fn upload(&self) -> DeltaUpload {
        let count = self.writes.len() as u32;
        let (groups, groups_x) = crate::cull::grid_64(count);
        let mut params = [0u8; 16];
        params[..4].copy_from_slice(&count.to_le_bytes());
        params[4..8].copy_from_slice(&groups_x.to_le_bytes());
        DeltaUpload {
            writes: self
                .to_words()
                .iter()
                .flat_map(|w| w.to_le_bytes())
                .collect(),
            params,
            groups,
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

/// A frame's delta upload ([`Deltas::upload`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeltaUpload {
    /// The writes, little-endian words.
    pub writes: Vec<u8>,
    /// The `DeltaParams` uniform: write count, dispatch row width, padding.
    pub params: [u8; 16],
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
