//! The compact frame file `frames/frames.bin` (`cloth run --frames N
//! --frame-format bin`): a run's cloth frames in one binary file, 12
//! bytes a particle a frame, where OBJ frames at full precision take
//! about 60 and a text parse. Little-endian throughout:
//!
//! - `CLOTHFR1`, then `u32` particles `n` and `u32` triangles `m`;
//! - `m` triangles, three `u32` particle indices each;
//! - per frame, appended as the run goes: `u64` step, then `n` positions
//!   as three `f32` (m) each.
//!
//! Every section is a multiple of 4 bytes, so a reader can view the
//! positions in place as `f32` arrays.

use anyhow::{Context, Result, bail};
use std::io::Write;
use std::path::Path;

/// The file's name under `frames/`.
pub const FRAMES_FILE: &str = "frames.bin";

const MAGIC: &[u8; 8] = b"CLOTHFR1";
const HEAD: usize = 16;

/// Appends frames to a frame file.
pub struct FrameWriter {
    out: std::io::BufWriter<std::fs::File>,
    particles: usize,
}

impl FrameWriter {
    /// Creates `path` for a cloth of `particles` and `triangles`.
    pub fn create(path: &Path, particles: usize, triangles: &[[u32; 3]]) -> Result<Self> {
        let file = std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let mut out = std::io::BufWriter::new(file);
        let count = |n: usize, what: &str| u32::try_from(n).with_context(|| format!("{n} {what}: more than u32 holds"));
        let mut head = MAGIC.to_vec();
        head.extend(count(particles, "particles")?.to_le_bytes());
        head.extend(count(triangles.len(), "triangles")?.to_le_bytes());
        head.extend(triangles.iter().flatten().flat_map(|i| i.to_le_bytes()));
        out.write_all(&head).with_context(|| format!("writing {}", path.display()))?;
        Ok(Self { out, particles })
    }

    /// Appends the frame of `step` (positions in m, stored as f32).
    pub fn append(&mut self, step: u64, x: &[nalgebra::Vector3<f64>]) -> std::io::Result<()> {
        assert_eq!(x.len(), self.particles, "a frame of another cloth");
        let mut frame = Vec::with_capacity(8 + 12 * x.len());
        frame.extend(step.to_le_bytes());
        frame.extend(x.iter().flat_map(|p| [p.x, p.y, p.z]).flat_map(|c| (c as f32).to_le_bytes()));
        self.out.write_all(&frame)
    }

    /// Writes what is buffered.
    pub fn finish(mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// A frame file read back.
#[derive(Debug, Clone, PartialEq)]
pub struct Frames {
    /// The cloth's triangles.
    pub triangles: Vec<[u32; 3]>,
    /// Per frame, its step and positions (m).
    pub frames: Vec<(u64, Vec<[f32; 3]>)>,
}

impl Frames {
    /// Reads `path`; errors name the file and what is wrong with it.
    pub fn read(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        Self::parse(&bytes).with_context(|| format!("{}: not a frame file", path.display()))
    }

    /// The steps of `path`'s frames, from the header and each frame's
    /// first 8 bytes (the positions are skipped, not read).
    pub fn steps(path: &Path) -> Result<Vec<u64>> {
        use std::io::{Read, Seek, SeekFrom};
        let bad = || format!("{}: not a frame file", path.display());
        let mut file = std::fs::File::open(path).with_context(|| format!("reading {}", path.display()))?;
        let len = file.metadata().with_context(|| format!("reading {}", path.display()))?.len();
        let mut head = [0u8; HEAD];
        file.read_exact(&mut head).with_context(bad)?;
        if &head[..8] != MAGIC {
            return Err(anyhow::anyhow!("no CLOTHFR1 header")).with_context(bad);
        }
        let word = |at: usize| u32::from_le_bytes(head[at..at + 4].try_into().expect("four bytes")) as u64;
        let (n, m) = (word(8), word(12));
        let (start, frame_len) = (HEAD as u64 + 12 * m, 8 + 12 * n);
        let body = len.checked_sub(start).context("cut short in the triangles").with_context(bad)?;
        if body % frame_len != 0 {
            bail!("{}: {body} bytes of frames are not a whole number of {frame_len}-byte frames", path.display());
        }
        (0..body / frame_len)
            .map(|k| {
                let mut step = [0u8; 8];
                file.seek(SeekFrom::Start(start + k * frame_len)).and_then(|_| file.read_exact(&mut step))?;
                Ok(u64::from_le_bytes(step))
            })
            .collect::<std::io::Result<_>>()
            .with_context(|| format!("reading {}", path.display()))
    }

    /// Parses a frame file's bytes.
    pub fn parse(bytes: &[u8]) -> Result<Self> {
        let word = |at: usize| -> Result<u32> {
            let b = bytes.get(at..at + 4).context("cut short")?;
            Ok(u32::from_le_bytes(b.try_into().expect("four bytes")))
        };
        if bytes.get(..8) != Some(MAGIC) {
            bail!("no CLOTHFR1 header");
        }
        let (n, m) = (word(8)? as usize, word(12)? as usize);
        let faces_end = HEAD + 12 * m;
        let triangles: Vec<[u32; 3]> = (0..m)
            .map(|t| Ok([word(HEAD + 12 * t)?, word(HEAD + 12 * t + 4)?, word(HEAD + 12 * t + 8)?]))
            .collect::<Result<_>>()?;
        if let Some(bad) = triangles.iter().flatten().find(|&&i| i as usize >= n) {
            bail!("a triangle names particle {bad} of {n}");
        }
        let frame_len = 8 + 12 * n;
        let body = bytes.len().checked_sub(faces_end).context("cut short in the triangles")?;
        if body % frame_len != 0 {
            bail!("{body} bytes of frames are not a whole number of {frame_len}-byte frames");
        }
        let frames = bytes[faces_end..]
            .chunks_exact(frame_len)
            .map(|f| {
                let step = u64::from_le_bytes(f[..8].try_into().expect("eight bytes"));
                let coords: Vec<f32> =
                    f[8..].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().expect("four bytes"))).collect();
                (step, coords.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
            })
            .collect();
        Ok(Self { triangles, frames })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_read_back_as_written_and_bad_files_are_named() {
        let path = std::env::temp_dir().join(format!("cloth-frames-{}.bin", std::process::id()));
        let x: Vec<nalgebra::Vector3<f64>> = (0..4).map(|i| nalgebra::Vector3::new(i as f64, 0.5, -0.25)).collect();
        let mut w = FrameWriter::create(&path, 4, &[[0, 1, 2], [1, 3, 2]]).unwrap();
        w.append(0, &x).unwrap();
        w.append(5, &x.iter().map(|p| p * 2.0).collect::<Vec<_>>()).unwrap();
        w.finish().unwrap();
        let back = Frames::read(&path).unwrap();
        assert_eq!(back.triangles, vec![[0, 1, 2], [1, 3, 2]]);
        assert_eq!(back.frames.iter().map(|f| f.0).collect::<Vec<_>>(), [0, 5]);
        assert_eq!(Frames::steps(&path).unwrap(), [0, 5]);
        assert_eq!(back.frames[1].1[3], [6.0, 1.0, -0.5]);
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(bytes.len(), 16 + 24 + 2 * (8 + 48));
        let err = |b: &[u8]| format!("{:#}", Frames::parse(b).unwrap_err());
        assert!(err(&bytes[..bytes.len() - 4]).contains("not a whole number of 56-byte frames"));
        assert!(err(&bytes[..20]).contains("cut short"));
        assert!(err(b"CLOTHFR2").contains("no CLOTHFR1 header"));
        let cut = path.with_extension("cut");
        std::fs::write(&cut, &bytes[..bytes.len() - 4]).unwrap();
        assert!(format!("{:#}", Frames::steps(&cut).unwrap_err()).contains("not a whole number of 56-byte frames"));
        std::fs::remove_file(&cut).unwrap();
        let mut wrong = bytes.clone();
        wrong[16] = 9;
        assert!(err(&wrong).contains("a triangle names particle 9 of 4"));
        std::fs::remove_file(&path).unwrap();
    }
}
