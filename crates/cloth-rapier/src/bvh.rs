//! BVH motion capture files (Biovision hierarchy): a skeleton of joints
//! with offsets and channels, then one line of channel values per frame.
//!
//! ```text
//! HIERARCHY
//! ROOT Hips
//! {
//!   OFFSET 0 0 0
//!   CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
//!   JOINT LeftUpLeg
//!   {
//!     OFFSET 10 0 0
//!     CHANNELS 3 Zrotation Xrotation Yrotation
//!     End Site
//!     {
//!       OFFSET 0 -40 0
//!     }
//!   }
//! }
//! MOTION
//! Frames: 2
//! Frame Time: 0.0333333
//! 0 90 0 0 0 0 0 0 0
//! 0 90 0 0 0 0 10 0 0
//! ```
//!
//! Conventions (the format's own): rotation channels in degrees, applied
//! in the order listed (`Zrotation Xrotation Yrotation` is
//! `Rz * Rx * Ry`, each about the joint's axes as rotated so far); every
//! joint's frame at rest is parallel to the root's, offset by `OFFSET`
//! from its parent; a joint's rotation turns it and everything below it
//! about its own origin. The root's position is its `OFFSET` plus its
//! position channels (the offset is zero in most files). Lengths are in
//! the file's unit and its up axis is the file's: [`crate::motion`]
//! converts. Position channels of joints below the root are read and
//! checked, not used: a retargeted rig keeps its own bone lengths.

use nalgebra::{Unit, UnitQuaternion};
use std::path::{Path, PathBuf};

type Vec3 = nalgebra::Vector3<f64>;

/// One channel of a joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// Translation along the file's x, y or z (0, 1, 2), file units.
    Position(usize),
    /// Rotation about the joint's x, y or z (0, 1, 2), degrees.
    Rotation(usize),
}

/// One joint of the hierarchy (the root included).
#[derive(Debug, Clone, PartialEq)]
pub struct BvhJoint {
    /// Its name.
    pub name: String,
    /// Index of its parent (`None` for the root).
    pub parent: Option<usize>,
    /// Offset from the parent's origin at rest, file units.
    pub offset: Vec3,
    /// Its channels, in file order.
    pub channels: Vec<Channel>,
    /// Index of its first channel in a frame's values.
    pub first_value: usize,
}

/// A BVH file: the hierarchy (parents before children) and the frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Bvh {
    /// Joints in file order (a parent before its children; the root first).
    pub joints: Vec<BvhJoint>,
    /// Time between frames, s.
    pub frame_time_s: f64,
    /// Channel values, one row per frame, `values_per_frame` each.
    values: Vec<f64>,
    /// Channels per frame.
    pub values_per_frame: usize,
}

/// A BVH file that could not be read, with the line where it went wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}:{line}: {message}")]
pub struct BvhError {
    /// The file.
    pub file: PathBuf,
    /// Line number, from 1 (0: the file as a whole).
    pub line: usize,
    /// Why.
    pub message: String,
}

/// A cursor over whitespace-separated words with their line numbers.
struct Words<'a> {
    words: Vec<(usize, &'a str)>,
    next: usize,
    file: &'a Path,
}

impl<'a> Words<'a> {
    fn new(text: &'a str, file: &'a Path) -> Self {
        let words = text.lines().enumerate().flat_map(|(k, l)| l.split_whitespace().map(move |w| (k + 1, w))).collect();
        Self { words, next: 0, file }
    }

    fn line(&self) -> usize {
        self.words.get(self.next).or(self.words.last()).map_or(0, |w| w.0)
    }

    fn fail<T>(&self, message: String) -> Result<T, BvhError> {
        Err(BvhError { file: self.file.to_path_buf(), line: self.line(), message })
    }

    fn peek(&self) -> Option<&'a str> {
        self.words.get(self.next).map(|w| w.1)
    }

    fn take(&mut self, what: &str) -> Result<&'a str, BvhError> {
        match self.words.get(self.next) {
            Some(&(_, w)) => {
                self.next += 1;
                Ok(w)
            }
            None => self.fail(format!("the file ends where {what} should be")),
        }
    }

    fn expect(&mut self, word: &str) -> Result<(), BvhError> {
        let got = self.take(&format!("{word:?}"))?;
        if got == word {
            Ok(())
        } else {
            self.next -= 1;
            self.fail(format!("expected {word:?}, found {got:?}"))
        }
    }

    fn number(&mut self, what: &str) -> Result<f64, BvhError> {
        let w = self.take(what)?;
        match w.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => {
                self.next -= 1;
                self.fail(format!("{what}: {w:?} is not a finite number"))
            }
        }
    }

    fn count(&mut self, what: &str) -> Result<usize, BvhError> {
        let w = self.take(what)?;
        w.parse::<usize>().or_else(|_| {
            self.next -= 1;
            self.fail(format!("{what}: {w:?} is not a whole number"))
        })
    }
}

impl Bvh {
    /// Reads a BVH file.
    pub fn load(path: &Path) -> Result<Self, BvhError> {
        let text = std::fs::read_to_string(path).map_err(|e| BvhError {
            file: path.to_path_buf(),
            line: 0,
            message: e.to_string(),
        })?;
        Self::parse(&text, path)
    }

    /// Reads BVH text; `file` names it in errors.
    pub fn parse(text: &str, file: &Path) -> Result<Self, BvhError> {
        let mut w = Words::new(text, file);
        w.expect("HIERARCHY")?;
        w.expect("ROOT")?;
        let mut joints = Vec::new();
        read_joint(&mut w, None, &mut joints)?;
        w.expect("MOTION")?;
        w.expect("Frames:")?;
        let frames = w.count("the number of frames")?;
        w.expect("Frame")?;
        w.expect("Time:")?;
        let frame_time_s = w.number("the frame time")?;
        if frame_time_s <= 0.0 {
            w.next -= 1;
            return w.fail(format!("the frame time must be > 0 s, got {frame_time_s}"));
        }
        if frames == 0 {
            return w.fail("the file has no frames".into());
        }
        let values_per_frame: usize = joints.iter().map(|j: &BvhJoint| j.channels.len()).sum();
        // Each value is one word of the file: never reserve more than it holds.
        let left = w.words.len() - w.next;
        let mut values = Vec::with_capacity(frames.saturating_mul(values_per_frame).min(left));
        for frame in 0..frames {
            let line = w.line();
            if w.peek().is_none() {
                return w.fail(format!("the file ends at frame {frame} of the {frames} the header announces"));
            }
            for k in 0..values_per_frame {
                if w.words.get(w.next).is_none_or(|&(l, _)| l != line) {
                    return Err(BvhError {
                        file: file.to_path_buf(),
                        line,
                        message: format!("frame {frame} has {k} values, the hierarchy has {values_per_frame} channels"),
                    });
                }
                values.push(w.number(&format!("frame {frame}, value {k}"))?);
            }
            if w.peek().is_some() && w.words[w.next].0 == line {
                return w.fail(format!("frame {frame} has more than the hierarchy's {values_per_frame} channels"));
            }
        }
        if let Some(extra) = w.peek() {
            return w.fail(format!("{extra:?} after the {frames} frames the header announces"));
        }
        Ok(Self { joints, frame_time_s, values, values_per_frame })
    }

    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.values.len() / self.values_per_frame.max(1)
    }

    /// Index of the joint named `name`.
    pub fn joint(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    fn row(&self, frame: usize) -> &[f64] {
        &self.values[frame * self.values_per_frame..(frame + 1) * self.values_per_frame]
    }

    /// A joint's rotation relative to its parent at `frame`: its rotation
    /// channels composed in file order.
    pub fn local_rotation(&self, frame: usize, joint: usize) -> UnitQuaternion<f64> {
        let j = &self.joints[joint];
        let row = &self.row(frame)[j.first_value..j.first_value + j.channels.len()];
        j.channels.iter().zip(row).fold(UnitQuaternion::identity(), |q, (c, v)| match c {
            Channel::Rotation(axis) => {
                let mut a = Vec3::zeros();
                a[*axis] = 1.0;
                q * UnitQuaternion::from_axis_angle(&Unit::new_unchecked(a), v.to_radians())
            }
            Channel::Position(_) => q,
        })
    }

    /// The root's position at `frame`: its offset plus its position channels, file units.
    pub fn root_position(&self, frame: usize) -> Vec3 {
        let root = &self.joints[0];
        let row = &self.row(frame)[root.first_value..root.first_value + root.channels.len()];
        root.channels.iter().zip(row).fold(root.offset, |mut p, (c, v)| {
            if let Channel::Position(axis) = c {
                p[*axis] += v;
            }
            p
        })
    }

    /// Every joint's rotation in the file's frame at `frame` (parent times local), into `out`.
    pub fn global_rotations(&self, frame: usize, out: &mut Vec<UnitQuaternion<f64>>) {
        out.clear();
        for (k, j) in self.joints.iter().enumerate() {
            let parent = j.parent.map_or(UnitQuaternion::identity(), |p| out[p]);
            out.push(parent * self.local_rotation(frame, k));
        }
    }

    /// Every joint's origin in the file's frame at `frame` (file units), into `out`.
    pub fn global_positions(&self, frame: usize, out: &mut Vec<Vec3>) {
        let mut turns = Vec::new();
        self.global_rotations(frame, &mut turns);
        self.positions_from(frame, &turns, out);
    }

    /// Every joint's origin at `frame` given its [`Bvh::global_rotations`] `turns`, into `out`.
    pub fn positions_from(&self, frame: usize, turns: &[UnitQuaternion<f64>], out: &mut Vec<Vec3>) {
        out.clear();
        for j in &self.joints {
            let at = match j.parent {
                None => self.root_position(frame),
                Some(p) => out[p] + turns[p] * j.offset,
            };
            out.push(at);
        }
    }
}

/// Reads `name { OFFSET .. CHANNELS .. (JOINT ..)* (End Site {..})? }`.
fn read_joint(w: &mut Words<'_>, parent: Option<usize>, joints: &mut Vec<BvhJoint>) -> Result<(), BvhError> {
    let name = w.take("a joint name")?.to_string();
    if joints.iter().any(|j| j.name == name) {
        w.next -= 1;
        return w.fail(format!("joint {name:?} is defined twice"));
    }
    w.expect("{")?;
    w.expect("OFFSET")?;
    let offset = Vec3::new(w.number("OFFSET x")?, w.number("OFFSET y")?, w.number("OFFSET z")?);
    w.expect("CHANNELS")?;
    let n = w.count("the number of channels")?;
    if n > 6 {
        w.next -= 1;
        return w.fail(format!("CHANNELS {n}: a joint has at most 6 (three positions, three rotations)"));
    }
    let mut channels = Vec::with_capacity(n);
    for _ in 0..n {
        let c = w.take("a channel name")?;
        let channel = match c {
            "Xposition" => Channel::Position(0),
            "Yposition" => Channel::Position(1),
            "Zposition" => Channel::Position(2),
            "Xrotation" => Channel::Rotation(0),
            "Yrotation" => Channel::Rotation(1),
            "Zrotation" => Channel::Rotation(2),
            other => {
                w.next -= 1;
                return w.fail(format!("joint {name:?}: unknown channel {other:?}"));
            }
        };
        if channels.contains(&channel) {
            w.next -= 1;
            return w.fail(format!("joint {name:?}: channel {c:?} listed twice"));
        }
        channels.push(channel);
    }
    let first_value = joints.iter().map(|j| j.channels.len()).sum();
    let index = joints.len();
    joints.push(BvhJoint { name, parent, offset, channels, first_value });
    loop {
        match w.take("\"JOINT\", \"End Site\" or \"}\"")? {
            "JOINT" => read_joint(w, Some(index), joints)?,
            "End" => {
                w.expect("Site")?;
                w.expect("{")?;
                w.expect("OFFSET")?;
                for axis in ["x", "y", "z"] {
                    w.number(&format!("End Site OFFSET {axis}"))?;
                }
                w.expect("}")?;
            }
            "}" => return Ok(()),
            other => {
                w.next -= 1;
                return w.fail(format!("expected \"JOINT\", \"End Site\" or \"}}\", found {other:?}"));
            }
        }
    }
}
