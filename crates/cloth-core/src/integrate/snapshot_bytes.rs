//! A [`Snapshot`] as bytes, to keep on disk or send to another process
//! (start states shared by the workers of a vectorised environment), and
//! as the flat list of numbers a co-simulation unit's state embeds.
//!
//! Layout (little-endian): the tag `clothsnp`, the format's version
//! (`u32`), the particle count (`u64`), the stitch count (`u64`), the
//! integrator memory's entry count (`u32`) and each entry's name (`u16`
//! length, UTF-8), then the values of [`Snapshot::values`] as `f64`, then
//! a CRC-32 of everything before it. A snapshot cut short, changed in any
//! byte, or of another version is refused, never read; whether it fits a
//! simulation is decided by [`crate::Simulation::restore`].

use crate::{ClothState, IntegratorMemory, Snapshot, Vec3};

const TAG: &[u8; 8] = b"clothsnp";
/// The layout this build writes and reads.
pub const SNAPSHOT_FORMAT_VERSION: u32 = 1;
/// Values before the integrator's memory: time, steps, history flag, last step.
const HEAD: usize = 4;

/// Why bytes are not a snapshot ([`Snapshot::from_bytes`]), or numbers
/// not a snapshot's values ([`Snapshot::from_values`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SnapshotBytesError {
    /// The bytes do not start with the snapshot's tag.
    #[error("not a cloth snapshot (its first bytes are not `clothsnp`)")]
    NotASnapshot,
    /// Written by a build with another layout.
    #[error("snapshot format version {found}; this build reads version {reads}")]
    Version {
        /// The version the bytes hold.
        found: u32,
        /// The version this build reads.
        reads: u32,
    },
    /// The checksum does not match: bytes changed or cut short.
    #[error("the snapshot's checksum does not match: changed or cut short")]
    Checksum,
    /// The length is not what the counts in the header make it.
    #[error("{got} bytes of snapshot where its header makes {expected}")]
    Length {
        /// Bytes the header's counts need.
        expected: usize,
        /// Bytes there are.
        got: usize,
    },
    /// An integrator memory's name is not UTF-8.
    #[error("the name of integrator memory entry {index} is not UTF-8")]
    Name {
        /// The entry.
        index: usize,
    },
    /// A value is not of its kind (a step count that is not a whole
    /// number, a flag other than 0 or 1).
    #[error("{field} = {value}: {expected}")]
    Value {
        /// The value's name.
        field: &'static str,
        /// What it is.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
}

impl Snapshot {
    /// The snapshot as numbers: time (s), steps, the history flag (1 or
    /// 0), the last step (s), the integrator memory's values in its order,
    /// then `x`, `v`, `x_prev`, `v_prev` (m, m/s; 3 a particle each) and
    /// each stitch's state (1 closed, 0 open).
    pub fn values(&self) -> impl Iterator<Item = f64> + '_ {
        let s = &self.state;
        let flag = |b: bool| f64::from(u8::from(b));
        let head = [s.time_s, s.steps as f64, flag(s.has_history), s.last_dt_s];
        let memory = self.integrator.entries().iter().map(|(_, v)| *v);
        let vectors =
            [&s.x, &s.v, &s.x_prev, &s.v_prev].into_iter().flat_map(|a| a.iter().flat_map(|p| [p.x, p.y, p.z]));
        head.into_iter().chain(memory).chain(vectors).chain(s.stitches_closed.iter().map(move |&c| flag(c)))
    }

    /// How many numbers [`Snapshot::values`] gives for `particles`,
    /// `stitches` and `memory_entries`.
    pub fn value_count(particles: usize, stitches: usize, memory_entries: usize) -> usize {
        HEAD + memory_entries + 12 * particles + stitches
    }

    /// Reads numbers written by [`Snapshot::values`] for `particles` and
    /// `stitches`, the memory's names taken from `memory` (its values
    /// replaced). Refuses a count that does not match, a time, last step
    /// or memory value that is not finite (or a negative last step), a
    /// step count that is not a whole number and a flag other than 0 or 1;
    /// positions and velocities are [`crate::Simulation::restore`]'s to check.
    pub fn from_values(
        values: &[f64],
        particles: usize,
        stitches: usize,
        memory: &IntegratorMemory,
    ) -> Result<Self, SnapshotBytesError> {
        let m = memory.entries().len();
        let expected = Self::value_count(particles, stitches, m);
        if values.len() != expected {
            return Err(SnapshotBytesError::Length { expected: 8 * expected, got: 8 * values.len() });
        }
        let flag = |field, value: f64| match value {
            0.0 => Ok(false),
            1.0 => Ok(true),
            _ => Err(SnapshotBytesError::Value { field, value, expected: "0 or 1" }),
        };
        let steps = values[1];
        if !(steps >= 0.0 && steps <= 2f64.powi(53) && steps.fract() == 0.0) {
            return Err(SnapshotBytesError::Value { field: "steps", value: steps, expected: "a whole number >= 0" });
        }
        if !values[0].is_finite() {
            return Err(SnapshotBytesError::Value { field: "time_s", value: values[0], expected: "finite" });
        }
        if !(values[3].is_finite() && values[3] >= 0.0) {
            return Err(SnapshotBytesError::Value {
                field: "last_dt_s",
                value: values[3],
                expected: "finite and >= 0",
            });
        }
        if let Some(&value) = values[HEAD..HEAD + m].iter().find(|v| !v.is_finite()) {
            return Err(SnapshotBytesError::Value { field: "an integrator memory value", value, expected: "finite" });
        }
        let vectors = &values[HEAD + m..HEAD + m + 12 * particles];
        let vec3s = |k: usize| -> Vec<Vec3> {
            vectors[3 * k * particles..3 * (k + 1) * particles].chunks_exact(3).map(Vec3::from_column_slice).collect()
        };
        let stitches_closed = values[HEAD + m + 12 * particles..]
            .iter()
            .map(|&c| flag("a stitch's state", c))
            .collect::<Result<_, _>>()?;
        let state = ClothState {
            time_s: values[0],
            steps: steps as u64,
            has_history: flag("has_history", values[2])?,
            last_dt_s: values[3],
            x: vec3s(0),
            v: vec3s(1),
            x_prev: vec3s(2),
            v_prev: vec3s(3),
            stitches_closed,
        };
        let integrator = memory.with_values(&values[HEAD..HEAD + m]).expect("the count was checked");
        Ok(Self { state, integrator })
    }

    /// The snapshot as bytes (the layout in this module's doc), read back
    /// by [`Snapshot::from_bytes`] to the same bits.
    pub fn to_bytes(&self) -> Vec<u8> {
        let s = &self.state;
        let mut out = TAG.to_vec();
        out.extend_from_slice(&SNAPSHOT_FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(s.x.len() as u64).to_le_bytes());
        out.extend_from_slice(&(s.stitches_closed.len() as u64).to_le_bytes());
        let entries = self.integrator.entries();
        out.extend_from_slice(&(entries.len() as u32).to_le_bytes());
        for (name, _) in entries {
            // Names are the integrators' own short identifiers.
            let len = u16::try_from(name.len()).expect("an integrator memory name under 64 kB");
            out.extend_from_slice(&len.to_le_bytes());
            out.extend_from_slice(name.as_bytes());
        }
        for v in self.values() {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Reads bytes written by [`Snapshot::to_bytes`]. Bytes of another
    /// kind or version, cut short or changed are refused; whether the
    /// snapshot fits a simulation is [`crate::Simulation::restore`]'s to say.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, SnapshotBytesError> {
        let Some(rest) = bytes.strip_prefix(&TAG[..]) else {
            return Err(SnapshotBytesError::NotASnapshot);
        };
        // Version, two counts, the memory's count and the checksum.
        let fixed = 4 + 8 + 8 + 4 + 4;
        if rest.len() < fixed {
            return Err(SnapshotBytesError::Length { expected: TAG.len() + fixed, got: bytes.len() });
        }
        let (body, crc) = bytes.split_at(bytes.len() - 4);
        if crc32fast::hash(body).to_le_bytes() != crc {
            return Err(SnapshotBytesError::Checksum);
        }
        let mut reader = Reader { bytes: body, at: TAG.len() };
        let version = u32::from_le_bytes(reader.take()?);
        if version != SNAPSHOT_FORMAT_VERSION {
            return Err(SnapshotBytesError::Version { found: version, reads: SNAPSHOT_FORMAT_VERSION });
        }
        let too_long = SnapshotBytesError::Length { expected: usize::MAX, got: bytes.len() };
        let particles = usize::try_from(u64::from_le_bytes(reader.take()?)).map_err(|_| too_long.clone())?;
        let stitches = usize::try_from(u64::from_le_bytes(reader.take()?)).map_err(|_| too_long.clone())?;
        let entries = u32::from_le_bytes(reader.take()?) as usize;
        let mut names = Vec::new();
        for index in 0..entries {
            let len = u16::from_le_bytes(reader.take()?) as usize;
            let name = std::str::from_utf8(reader.slice(len)?).map_err(|_| SnapshotBytesError::Name { index })?;
            names.push((name.to_owned(), 0.0));
        }
        let count = 12usize
            .checked_mul(particles)
            .and_then(|c| c.checked_add(HEAD + entries))
            .and_then(|c| c.checked_add(stitches))
            .ok_or(too_long)?;
        let remaining = body.len() - reader.at;
        if count.checked_mul(8) != Some(remaining) {
            let expected = count.saturating_mul(8).saturating_add(reader.at + 4);
            return Err(SnapshotBytesError::Length { expected, got: bytes.len() });
        }
        let values: Vec<f64> =
            body[reader.at..].chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes"))).collect();
        Self::from_values(&values, particles, stitches, &IntegratorMemory::from_named(names))
    }
}

/// Reads the header's fields in order.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn slice(&mut self, len: usize) -> Result<&'a [u8], SnapshotBytesError> {
        let end = self.at.checked_add(len).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(SnapshotBytesError::Length {
                expected: self.at.saturating_add(len) + 4,
                got: self.bytes.len() + 4,
            });
        };
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N], SnapshotBytesError> {
        Ok(self.slice(N)?.try_into().expect("N bytes"))
    }
}
