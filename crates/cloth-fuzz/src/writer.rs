//! The glTF writer's input as a target: a recording decoded from bytes
//! (counts, indices in and out of range, any f64 bit pattern), written;
//! what the writer accepts must read back as valid glTF 2.0.

use cloth_tools::gltf::{Recording, SolidTrack, glb};

/// Reads counts, indices and numbers off the bytes, then zeros.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn byte(&mut self) -> u8 {
        let Some((&b, rest)) = self.0.split_first() else { return 0 };
        self.0 = rest;
        b
    }

    /// A count below `n`.
    fn count(&mut self, n: u8) -> usize {
        (self.byte() % n) as usize
    }

    /// Mostly ordinary numbers; one in four any bit pattern.
    fn number(&mut self) -> f64 {
        let kind = self.byte();
        if kind.is_multiple_of(4) {
            f64::from_le_bytes(std::array::from_fn(|_| self.byte()))
        } else {
            (kind as f64 - 128.0) / 16.0
        }
    }

    fn point(&mut self) -> [f64; 3] {
        std::array::from_fn(|_| self.number())
    }

    /// An index mostly below `n`, sometimes just beyond.
    fn index(&mut self, n: usize) -> u32 {
        (self.byte() as usize % (n + 2)) as u32
    }
}

pub(crate) fn gltf_writer(data: &[u8]) -> String {
    let mut b = Bytes(data);
    let (particles, frames, triangles, solids) = (b.count(9), b.count(5), b.count(6), b.count(3));
    let mut times: Vec<f64> = (0..frames).map(|k| k as f64 / 30.0).collect();
    if b.byte() % 3 == 0 {
        times.iter_mut().for_each(|t| *t = b.number());
    }
    if b.byte() % 4 == 0 {
        times.push(1.0);
    }
    let ragged = b.byte() % 5 == 0;
    let frames: Vec<Vec<[f64; 3]>> =
        (0..frames).map(|k| (0..particles + usize::from(ragged && k == 1)).map(|_| b.point()).collect()).collect();
    let triangles: Vec<[u32; 3]> = (0..triangles).map(|_| std::array::from_fn(|_| b.index(particles))).collect();
    let solids: Vec<SolidTrack> = (0..solids)
        .map(|_| {
            let vertices: Vec<[f64; 3]> = (0..b.count(6)).map(|_| b.point()).collect();
            let n = vertices.len();
            let triangles = (0..b.count(4)).map(|_| std::array::from_fn(|_| b.index(n))).collect();
            let poses = (0..frames.len() + usize::from(b.byte() % 7 == 0))
                .map(|_| std::array::from_fn(|_| b.number()))
                .collect();
            SolidTrack { vertices, triangles, poses }
        })
        .collect();
    let rec = Recording { times: &times, triangles: &triangles, frames: &frames, solids: &solids };
    match glb(&rec) {
        Err(e) => crate::readers::label(e),
        Ok(bytes) => {
            if let Err(e) = gltf::Gltf::from_slice(&bytes) {
                panic!("the writer accepted a recording and wrote a glTF that does not read back: {e}");
            }
            "ok".into()
        }
    }
}
