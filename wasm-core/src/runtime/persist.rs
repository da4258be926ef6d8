//! A character's runtime state as bytes, and back: what a shared room sends so that a late
//! joiner's copy of a person continues from the person's own floats (docs/rooms.md, "Late
//! joiners"). Each stateful struct lists its fields once, in [`Persist::persist`]; the same list
//! writes ([`StateWriter`]) and reads ([`StateReader`]), so the two orders cannot diverge.
//!
//! The bytes are untrusted when they come from the network: the reader refuses a short or long
//! buffer, a float that is not finite or beyond ±[`MAX_STATE_VALUE`], a rotation that is not a
//! unit quaternion and a length other than the receiving character's, and names the first
//! problem. Little-endian; floats are stored bit-exact (no quantization, or the copy would not
//! be the sender's floats).

use glam::{Quat, Vec2, Vec3};

/// Largest magnitude of any stored float: positions stay within ±1e5 m, speeds and offsets far
/// below; beyond this a value is garbage that would overflow a few updates later.
pub const MAX_STATE_VALUE: f32 = 1e6;

/// Visits values in order: writes them, or overwrites them with what was read.
pub trait Visitor {
    fn f32(&mut self, x: &mut f32, what: &'static str);
    fn u32(&mut self, x: &mut u32, what: &'static str);
    /// A run of values whose count the receiver already knows (from its database): the reader
    /// checks the stored count against it.
    fn count(&mut self, n: usize, what: &'static str);
    /// Reading: a rotation read in place is checked to be a unit quaternion.
    fn quat(&mut self, q: &mut Quat, what: &'static str) {
        let mut a = q.to_array();
        for x in &mut a {
            self.f32(x, what);
        }
        *q = Quat::from_array(a);
    }
    /// Reading (values are replaced) or writing (values are only read).
    fn reading(&self) -> bool;
    /// Reading: records a problem (the first one is reported).
    fn fail(&mut self, problem: String);
}

/// A struct (or value) that is part of the runtime state.
pub trait Persist {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str);
}

impl Persist for f32 {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        v.f32(self, what);
    }
}
impl Persist for u32 {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        v.u32(self, what);
    }
}
impl Persist for usize {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        let mut x = *self as u32;
        v.u32(&mut x, what);
        *self = x as usize;
    }
}
impl Persist for u8 {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        let mut x = *self as u32;
        v.u32(&mut x, what);
        if x > u8::MAX as u32 {
            v.fail(format!("{what} is {x} (a byte)"));
        }
        *self = x as u8;
    }
}
impl Persist for bool {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        let mut x = *self as u32;
        v.u32(&mut x, what);
        if x > 1 {
            v.fail(format!("{what} is {x} (a flag: 0 or 1)"));
        }
        *self = x == 1;
    }
}
impl Persist for Vec3 {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        v.f32(&mut self.x, what);
        v.f32(&mut self.y, what);
        v.f32(&mut self.z, what);
    }
}
impl Persist for Quat {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        v.quat(self, what);
    }
}
impl Persist for Vec2 {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        v.f32(&mut self.x, what);
        v.f32(&mut self.y, what);
    }
}
impl<T: Persist, const N: usize> Persist for [T; N] {
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        for x in self {
            x.persist(v, what);
        }
    }
}
impl<T: Persist> Persist for Vec<T> {
    /// The length is the receiver's (set by its database); a stored one that differs is refused.
    fn persist(&mut self, v: &mut dyn Visitor, what: &'static str) {
        v.count(self.len(), what);
        for x in self {
            x.persist(v, what);
        }
    }
}

/// Writes visited values as little-endian bytes.
#[derive(Default)]
pub struct StateWriter {
    pub bytes: Vec<u8>,
}

impl Visitor for StateWriter {
    fn f32(&mut self, x: &mut f32, _: &'static str) {
        self.bytes.extend_from_slice(&x.to_le_bytes());
    }
    fn u32(&mut self, x: &mut u32, _: &'static str) {
        self.bytes.extend_from_slice(&x.to_le_bytes());
    }
    fn count(&mut self, n: usize, _: &'static str) {
        self.bytes.extend_from_slice(&(n as u32).to_le_bytes());
    }
    fn reading(&self) -> bool {
        false
    }
    fn fail(&mut self, _: String) {}
}

/// Reads visited values from bytes, checking each; after the first problem it reads nothing
/// more (values keep what they had) and [`StateReader::finish`] reports it.
pub struct StateReader<'a> {
    bytes: &'a [u8],
    at: usize,
    problem: Option<String>,
}

impl<'a> StateReader<'a> {
    pub fn new(bytes: &'a [u8]) -> Self {
        StateReader { bytes, at: 0, problem: None }
    }

    fn take4(&mut self, what: &'static str) -> Option<[u8; 4]> {
        if self.problem.is_some() {
            return None;
        }
        match self.bytes.get(self.at..self.at + 4) {
            Some(b) => {
                self.at += 4;
                Some([b[0], b[1], b[2], b[3]])
            }
            None => {
                self.problem = Some(format!("the state ends at byte {} before {what}", self.bytes.len()));
                None
            }
        }
    }

    /// The first problem, or one if bytes are left over.
    pub fn finish(self) -> Result<(), String> {
        match self.problem {
            Some(p) => Err(p),
            None if self.at != self.bytes.len() => {
                Err(format!("the state has {} bytes after its end (byte {})", self.bytes.len() - self.at, self.at))
            }
            None => Ok(()),
        }
    }
}

impl Visitor for StateReader<'_> {
    fn f32(&mut self, x: &mut f32, what: &'static str) {
        if let Some(b) = self.take4(what) {
            let value = f32::from_le_bytes(b);
            if !(value.abs() <= MAX_STATE_VALUE) {
                self.problem =
                    Some(format!("{what} is {value} at byte {} (finite, within ±{MAX_STATE_VALUE:e})", self.at - 4));
                return;
            }
            *x = value;
        }
    }
    fn u32(&mut self, x: &mut u32, what: &'static str) {
        if let Some(b) = self.take4(what) {
            *x = u32::from_le_bytes(b);
        }
    }
    fn count(&mut self, n: usize, what: &'static str) {
        let mut stored = 0;
        let before = self.problem.is_none();
        self.u32(&mut stored, what);
        if before && self.problem.is_none() && stored as usize != n {
            self.problem = Some(format!("{what} has {stored} values, this character {n} (another database?)"));
        }
    }
    fn quat(&mut self, q: &mut Quat, what: &'static str) {
        let mut a = q.to_array();
        for x in &mut a {
            self.f32(x, what);
        }
        if self.problem.is_none() {
            let read = Quat::from_array(a);
            if (read.length() - 1.0).abs() > 1e-3 {
                self.problem = Some(format!(
                    "{what} is not a unit quaternion (length {}) at byte {}",
                    read.length(),
                    self.at - 16
                ));
                return;
            }
            *q = read;
        }
    }
    fn reading(&self) -> bool {
        true
    }
    fn fail(&mut self, problem: String) {
        self.problem.get_or_insert(problem);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_round_trip_bit_exact() {
        let mut a =
            (1.0f32 / 3.0, Vec3::new(-0.1, 2e5, 7.0), Quat::from_rotation_y(0.3), vec![Vec3::ONE; 3], true, 9usize);
        let mut w = StateWriter::default();
        let visit = |v: &mut dyn Visitor, a: &mut (f32, Vec3, Quat, Vec<Vec3>, bool, usize)| {
            a.0.persist(v, "a");
            a.1.persist(v, "b");
            a.2.persist(v, "c");
            a.3.persist(v, "d");
            a.4.persist(v, "e");
            a.5.persist(v, "f");
        };
        visit(&mut w, &mut a);
        let mut b = (0.0, Vec3::ZERO, Quat::IDENTITY, vec![Vec3::ZERO; 3], false, 0usize);
        let mut r = StateReader::new(&w.bytes);
        visit(&mut r, &mut b);
        r.finish().unwrap();
        assert_eq!(a.0.to_bits(), b.0.to_bits());
        assert_eq!((a.1, a.2, &a.3, a.4, a.5), (b.1, b.2, &b.3, b.4, b.5));
    }

    #[test]
    fn bad_bytes_are_named_and_nothing_past_them_is_read() {
        let write = |values: &[f32]| values.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let mut v = Vec3::ZERO;
        let bytes = write(&[1.0, f32::NAN, 3.0]);
        let mut r = StateReader::new(&bytes);
        v.persist(&mut r, "the root");
        assert_eq!(v, Vec3::new(1.0, 0.0, 0.0));
        let e = r.finish().unwrap_err();
        assert!(e.contains("the root is NaN at byte 4"), "{e}");

        let bytes = write(&[2.0, 0.0, 0.0, 0.0]);
        let mut q = Quat::IDENTITY;
        let mut r = StateReader::new(&bytes);
        q.persist(&mut r, "a rotation");
        assert_eq!(q, Quat::IDENTITY);
        assert!(r.finish().unwrap_err().contains("not a unit quaternion"));

        let mut r = StateReader::new(&bytes[..6]);
        q.persist(&mut r, "a rotation");
        assert!(r.finish().unwrap_err().contains("ends at byte 6 before a rotation"));

        let mut r = StateReader::new(&bytes);
        let mut x = 0.0f32;
        x.persist(&mut r, "x");
        assert!(r.finish().unwrap_err().contains("12 bytes after its end"));

        let mut bytes = 4u32.to_le_bytes().to_vec();
        bytes.extend(write(&[0.0; 12]));
        let mut joints = vec![Vec3::ZERO; 3];
        let mut r = StateReader::new(&bytes);
        joints.persist(&mut r, "joint positions");
        assert!(r.finish().unwrap_err().contains("joint positions has 4 values, this character 3"));
    }
}
