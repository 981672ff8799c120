//! Snapshots of a stream: the bytes a session's whole state is saved to, and read back from, so
//! that a stream can stop in one process and go on in another, bit for bit (issue 38; the
//! families write their fields, this module frames and checks them).
//!
//! Layout, little-endian:
//!
//! | bytes | what |
//! |---|---|
//! | 8 | magic `TRPSNAP\0` |
//! | 4 | format version ([`FORMAT_VERSION`]) |
//! | 4 + n | the family's name (`armflow`, ...), at most [`MAX_FAMILY_BYTES`] |
//! | 32 | the model's identity: a digest of its bundle, so a snapshot cannot go to another model |
//! | 8 | payload length |
//! | payload | the family's fields, in the order it writes them |
//! | 4 | CRC-32 (IEEE) of every byte before it |
//!
//! A snapshot is hostile input: the header, its length and its checksum are checked before the
//! payload is read, and every field's length before anything is allocated for it (against the
//! bytes left and against the caller's bound), so a truncated, altered or absurd snapshot is an
//! error, never an allocation of its claimed size.

use crate::shared::error::{Error, Result};

/// The first bytes of every snapshot.
pub const MAGIC: [u8; 8] = *b"TRPSNAP\0";
/// The first bytes of every sealed snapshot (`shared/sealed.rs`), which a plain restore names.
pub const SEALED_MAGIC: [u8; 8] = *b"TRPSEAL\0";
/// The layout written; a reader refuses any other.
pub const FORMAT_VERSION: u32 = 3;
/// The longest family name a snapshot may carry.
pub const MAX_FAMILY_BYTES: usize = 32;
/// Bytes of the model's identity.
pub const MODEL_ID_BYTES: usize = 32;

/// The error of a snapshot that does not hold what it should.
pub(crate) fn bad(message: impl Into<String>) -> Error {
    Error::InvalidInput(format!("snapshot: {}", message.into()))
}

/// Refuses a run of stored values with a NaN or an infinity: no stream state holds one (every
/// step checks its outputs), so one in a snapshot is damage or an edit, and restoring it would
/// leave a session whose every step fails.
fn all_finite<T: Copy + Into<f64>>(what: &str, values: &[T]) -> Result<()> {
    match values.iter().position(|&v| !v.into().is_finite()) {
        None => Ok(()),
        Some(i) => Err(bad(format!(
            "{what}: value {i} of {} is {}, not finite",
            values.len(),
            values[i].into()
        ))),
    }
}

/// The error of a family whose streams have no snapshot yet.
pub(crate) fn cannot_snapshot(family: &str) -> Error {
    Error::Unsupported(format!(
        "snapshots: `{family}` streams cannot be saved and restored"
    ))
}

/// A snapshot being written: the header first, then the family's fields as it appends them;
/// [`SnapshotWriter::finish`] fills in the payload's length and appends the checksum (one buffer,
/// never copied).
pub struct SnapshotWriter {
    bytes: Vec<u8>,
    /// Where the payload's length goes, and where the payload starts.
    length_at: usize,
}

impl SnapshotWriter {
    /// A snapshot of a `family` stream of the model `model`, its buffer sized for about
    /// `payload_hint` bytes of fields.
    pub fn new(family: &str, model: &[u8; MODEL_ID_BYTES], payload_hint: usize) -> Self {
        // Family names are the crate's own constants.
        debug_assert!(family.len() <= MAX_FAMILY_BYTES, "family name too long");
        let mut bytes = Vec::with_capacity(64 + family.len() + payload_hint);
        bytes.extend_from_slice(&MAGIC);
        bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        bytes.extend_from_slice(&(family.len() as u32).to_le_bytes());
        bytes.extend_from_slice(family.as_bytes());
        bytes.extend_from_slice(model);
        let length_at = bytes.len();
        bytes.extend_from_slice(&0u64.to_le_bytes());
        Self { bytes, length_at }
    }

    /// Appends a `u32`.
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// Appends a `u64`.
    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// Appends an `f32`, bit for bit.
    pub fn f32(&mut self, v: f32) -> &mut Self {
        self.u32(v.to_bits())
    }

    /// Appends an `f64`, bit for bit.
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.u64(v.to_bits())
    }

    /// Appends a flag.
    pub fn bool(&mut self, v: bool) -> &mut Self {
        self.bytes.push(u8::from(v));
        self
    }

    /// Appends a length-prefixed run of `f32`s, bit for bit.
    pub fn f32s(&mut self, v: &[f32]) -> &mut Self {
        self.u64(v.len() as u64);
        self.f32s_raw(v)
    }

    /// Appends `f32`s bit for bit, without a length (the reader knows it).
    pub fn f32s_raw(&mut self, v: &[f32]) -> &mut Self {
        #[cfg(target_endian = "little")]
        {
            // SAFETY: an f32 is 4 initialised bytes without padding; on a little-endian target
            // its bytes in memory are its little-endian encoding. A memory copy, not a loop.
            let bytes = unsafe {
                std::slice::from_raw_parts(v.as_ptr().cast::<u8>(), std::mem::size_of_val(v))
            };
            self.bytes.extend_from_slice(bytes);
        }
        #[cfg(not(target_endian = "little"))]
        for x in v {
            self.bytes.extend_from_slice(&x.to_bits().to_le_bytes());
        }
        self
    }

    /// Appends a length-prefixed run of `f64`s, bit for bit.
    pub fn f64s(&mut self, v: &[f64]) -> &mut Self {
        self.u64(v.len() as u64);
        for x in v {
            self.f64(*x);
        }
        self
    }

    /// Appends a length-prefixed UTF-8 string.
    pub fn str(&mut self, v: &str) -> &mut Self {
        self.u64(v.len() as u64);
        self.bytes.extend_from_slice(v.as_bytes());
        self
    }

    /// The snapshot: header, payload, checksum.
    pub fn finish(mut self) -> Vec<u8> {
        let payload = (self.bytes.len() - self.length_at - 8) as u64;
        self.bytes[self.length_at..self.length_at + 8].copy_from_slice(&payload.to_le_bytes());
        let crc = crc32fast::hash(&self.bytes);
        self.bytes.extend_from_slice(&crc.to_le_bytes());
        self.bytes
    }
}

/// A snapshot being read: opened only once its frame checks out; each read checks what is left.
pub struct SnapshotReader<'a> {
    rest: &'a [u8],
}

/// Takes `n` bytes from the front of `bytes`, or says what was missing.
fn take<'a>(bytes: &mut &'a [u8], n: usize, what: &str) -> Result<&'a [u8]> {
    if bytes.len() < n {
        return Err(bad(format!(
            "truncated: {what} needs {n} bytes, {} left",
            bytes.len()
        )));
    }
    let (head, tail) = bytes.split_at(n);
    *bytes = tail;
    Ok(head)
}

/// Decodes little-endian `f32`s from `bytes` (`4 * dst.len()` of them) into `dst`.
fn floats_from(bytes: &[u8], dst: &mut [f32]) {
    #[cfg(target_endian = "little")]
    {
        let n = bytes.len().min(std::mem::size_of_val(dst));
        // SAFETY: `n` bytes fit in both, any 4 bytes are a valid f32, and the two do not overlap
        // (one is the snapshot, the other a buffer of the caller's). A memory copy, not a loop.
        unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), dst.as_mut_ptr().cast::<u8>(), n) };
    }
    #[cfg(not(target_endian = "little"))]
    for (x, c) in dst.iter_mut().zip(bytes.chunks_exact(4)) {
        *x = f32::from_bits(u32_of(c));
    }
}

fn u32_of(b: &[u8]) -> u32 {
    u32::from_le_bytes(b.try_into().expect("4 bytes"))
}

fn u64_of(b: &[u8]) -> u64 {
    u64::from_le_bytes(b.try_into().expect("8 bytes"))
}

impl<'a> SnapshotReader<'a> {
    /// Checks the frame of `bytes` (magic, version, the family `family`, the model `model`, the
    /// payload's length, the checksum) and opens its payload.
    pub fn open(bytes: &'a [u8], family: &str, model: &[u8; MODEL_ID_BYTES]) -> Result<Self> {
        let mut b = bytes;
        if bytes.starts_with(&SEALED_MAGIC) {
            return Err(bad(
                "it is sealed with a key: restore it with that key (restore_sealed)",
            ));
        }
        if take(&mut b, 8, "the magic")? != MAGIC {
            return Err(bad("not a troupe snapshot (no TRPSNAP magic)"));
        }
        let version = u32_of(take(&mut b, 4, "the version")?);
        if version != FORMAT_VERSION {
            return Err(bad(format!(
                "format version {version}; this troupe reads version {FORMAT_VERSION}"
            )));
        }
        let n = u32_of(take(&mut b, 4, "the family's length")?) as usize;
        if n > MAX_FAMILY_BYTES {
            return Err(bad(format!("a family name of {n} bytes")));
        }
        let name = take(&mut b, n, "the family's name")?;
        if name != family.as_bytes() {
            return Err(bad(format!(
                "a `{}` stream's, not a `{family}` stream's",
                String::from_utf8_lossy(name)
            )));
        }
        if take(&mut b, MODEL_ID_BYTES, "the model's identity")? != model {
            return Err(bad("taken from another model (its bundle differs)"));
        }
        let len = u64_of(take(&mut b, 8, "the payload's length")?);
        let holds = b.len().saturating_sub(4) as u64;
        if len > holds || b.len() < 4 {
            return Err(bad(format!(
                "truncated: the header says {len} payload bytes, {holds} are there"
            )));
        }
        if len < holds {
            return Err(bad(format!(
                "{} bytes after the end the header gives",
                holds - len
            )));
        }
        let (body, crc) = bytes.split_at(bytes.len() - 4);
        if crc32fast::hash(body) != u32_of(crc) {
            return Err(bad("checksum mismatch: the bytes were altered or damaged"));
        }
        Ok(Self {
            rest: &b[..b.len() - 4],
        })
    }

    /// Reads a `u32`.
    pub fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32_of(take(&mut self.rest, 4, what)?))
    }

    /// Reads a `u64`.
    pub fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64_of(take(&mut self.rest, 8, what)?))
    }

    /// Reads an `f32`.
    pub fn f32(&mut self, what: &str) -> Result<f32> {
        Ok(f32::from_bits(self.u32(what)?))
    }

    /// Reads an `f64`.
    pub fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_bits(self.u64(what)?))
    }

    /// Reads a flag (0 or 1).
    pub fn bool(&mut self, what: &str) -> Result<bool> {
        match take(&mut self.rest, 1, what)?[0] {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(bad(format!("{what}: {v} is not a flag"))),
        }
    }

    /// The bytes of a length-prefixed run of at most `max` values of `width` bytes: the claimed
    /// length is checked against `max` and against the bytes left before anything is allocated.
    fn run(&mut self, what: &str, max: usize, width: usize) -> Result<&'a [u8]> {
        let n = self.count(what, max)?;
        let need = n
            .checked_mul(width)
            .ok_or_else(|| bad(format!("{what}: {n} values")))?;
        take(&mut self.rest, need, what)
    }

    /// Reads a run of finite `f32`s of at most `max` values (checked before anything is
    /// allocated).
    pub fn f32s(&mut self, what: &str, max: usize) -> Result<Vec<f32>> {
        let bytes = self.run(what, max, 4)?;
        let mut v = vec![0f32; bytes.len() / 4];
        floats_from(bytes, &mut v);
        all_finite(what, &v)?;
        Ok(v)
    }

    /// Fails unless at least `n` bytes are left (before allocating what they will fill).
    pub fn expect_bytes(&self, what: &str, n: usize) -> Result<()> {
        if self.rest.len() < n {
            return Err(bad(format!(
                "truncated: {what} needs {n} bytes, {} left",
                self.rest.len()
            )));
        }
        Ok(())
    }

    /// Reads exactly `dst.len()` finite `f32`s written by [`SnapshotWriter::f32s_raw`] into
    /// `dst` (which holds them, or some of them, when they are not all finite).
    pub fn f32s_into(&mut self, what: &str, dst: &mut [f32]) -> Result<()> {
        let bytes = take(&mut self.rest, dst.len() * 4, what)?;
        floats_from(bytes, dst);
        all_finite(what, dst)
    }

    /// Reads a run of exactly `n` `f32`s ([`SnapshotReader::f32s`] then the count checked).
    pub fn f32s_exact(&mut self, what: &str, n: usize) -> Result<Vec<f32>> {
        let v = self.f32s(what, n)?;
        if v.len() != n {
            return Err(bad(format!("{what}: {} values, not {n}", v.len())));
        }
        Ok(v)
    }

    /// Reads a run of finite `f64`s of at most `max` values (checked before anything is
    /// allocated).
    pub fn f64s(&mut self, what: &str, max: usize) -> Result<Vec<f64>> {
        let v: Vec<f64> = self
            .run(what, max, 8)?
            .chunks_exact(8)
            .map(|c| f64::from_bits(u64_of(c)))
            .collect();
        all_finite(what, &v)?;
        Ok(v)
    }

    /// Reads a count of at most `max` (of items that follow).
    pub fn count(&mut self, what: &str, max: usize) -> Result<usize> {
        let n = self.u64(what)?;
        if n > max as u64 {
            return Err(bad(format!("{what}: {n}, at most {max} here")));
        }
        Ok(n as usize)
    }

    /// Reads a finite `f64` (a setting or a position: NaN and infinities are refused).
    pub fn finite(&mut self, what: &str) -> Result<f64> {
        let v = self.f64(what)?;
        if !v.is_finite() {
            return Err(bad(format!("{what}: {v} is not finite")));
        }
        Ok(v)
    }

    /// Reads a length in metres (a position, an offset, a shift): finite and within `±bound`
    /// (the world's, for positions). A larger one, finite as it is, would overflow the float32
    /// frames it is added to.
    pub fn metres(&mut self, what: &str, bound: f64) -> Result<f64> {
        let v = self.finite(what)?;
        if v.abs() > bound {
            return Err(bad(format!("{what}: {v} m, beyond {bound} m")));
        }
        Ok(v)
    }

    /// Reads a UTF-8 string of at most `max` bytes.
    pub fn str(&mut self, what: &str, max: usize) -> Result<String> {
        let bytes = self.run(what, max, 1)?;
        String::from_utf8(bytes.to_vec()).map_err(|_| bad(format!("{what}: not UTF-8")))
    }

    /// Ends the read: every byte must have been taken.
    pub fn finish(self) -> Result<()> {
        if self.rest.is_empty() {
            Ok(())
        } else {
            Err(bad(format!(
                "{} bytes after the last field",
                self.rest.len()
            )))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODEL: [u8; MODEL_ID_BYTES] = [7; MODEL_ID_BYTES];

    fn sample() -> Vec<u8> {
        let mut w = SnapshotWriter::new("armflow", &MODEL, 0);
        w.u32(3)
            .u64(u64::MAX)
            .f32(-0.0)
            .f64(f64::NAN)
            .bool(true)
            .f32s(&[1.5, f32::MAX, -2.0])
            .f64s(&[0.25])
            .str("mirror");
        w.finish()
    }

    #[test]
    fn fields_come_back_bit_for_bit() {
        let bytes = sample();
        let mut r = SnapshotReader::open(&bytes, "armflow", &MODEL).unwrap();
        assert_eq!(r.u32("a").unwrap(), 3);
        assert_eq!(r.u64("b").unwrap(), u64::MAX);
        assert_eq!(r.f32("c").unwrap().to_bits(), (-0.0f32).to_bits());
        assert_eq!(r.f64("d").unwrap().to_bits(), f64::NAN.to_bits());
        assert!(r.bool("e").unwrap());
        let v = r.f32s("f", 3).unwrap();
        assert_eq!(v[0], 1.5);
        assert_eq!(v[1], f32::MAX);
        assert_eq!(r.f64s("g", 1).unwrap(), [0.25]);
        assert_eq!(r.str("h", 6).unwrap(), "mirror");
        r.finish().unwrap();
    }

    /// No stream state holds a NaN or an infinity, so a run with one (its checksum repaired) is
    /// refused, naming the field and the value, whichever reader takes it.
    #[test]
    fn runs_of_values_that_are_not_finite_are_refused() {
        for bad_value in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let mut w = SnapshotWriter::new("armflow", &MODEL, 0);
            w.f32s(&[0.0, bad_value])
                .f32s_raw(&[1.0, 2.0, bad_value])
                .f64s(&[1.0, f64::from(bad_value)]);
            let bytes = w.finish();
            let mut r = SnapshotReader::open(&bytes, "armflow", &MODEL).unwrap();
            let e = r.f32s("the latents", 2).unwrap_err().to_string();
            assert!(e.contains("the latents: value 1 of 2"), "{e}");
            let e = r.f32s_into("the keys", &mut [0.0; 3]).unwrap_err();
            assert!(e.to_string().contains("the keys: value 2 of 3"), "{e}");
            let e = r.f64s("the last frame", 2).unwrap_err().to_string();
            assert!(e.contains("not finite"), "{e}");
        }
    }

    #[test]
    fn every_truncation_and_every_flipped_bit_is_refused() {
        let bytes = sample();
        for n in 0..bytes.len() {
            assert!(SnapshotReader::open(&bytes[..n], "armflow", &MODEL).is_err());
        }
        for i in 0..bytes.len() {
            for bit in 0..8 {
                let mut b = bytes.clone();
                b[i] ^= 1 << bit;
                assert!(
                    SnapshotReader::open(&b, "armflow", &MODEL).is_err(),
                    "byte {i} bit {bit}"
                );
            }
        }
    }

    #[test]
    fn another_family_model_or_version_is_refused_by_name() {
        let bytes = sample();
        let e = SnapshotReader::open(&bytes, "magnet", &MODEL)
            .err()
            .unwrap();
        assert!(e.to_string().contains("`armflow` stream"), "{e}");
        let e = SnapshotReader::open(&bytes, "armflow", &[0; MODEL_ID_BYTES])
            .err()
            .unwrap();
        assert!(e.to_string().contains("another model"), "{e}");
        let mut b = bytes.clone();
        b[8] = 9;
        let e = SnapshotReader::open(&b, "armflow", &MODEL).err().unwrap();
        assert!(e.to_string().contains("version 9"), "{e}");
    }

    #[test]
    fn absurd_lengths_are_refused_before_allocating() {
        // A well-framed snapshot whose one field claims 2^61 floats.
        let mut w = SnapshotWriter::new("armflow", &MODEL, 8);
        w.u64(1 << 61);
        let bytes = w.finish();
        let mut r = SnapshotReader::open(&bytes, "armflow", &MODEL).unwrap();
        let e = r.f32s("cache", usize::MAX).err().unwrap();
        assert!(e.to_string().contains("truncated"), "{e}");
        let mut r = SnapshotReader::open(&bytes, "armflow", &MODEL).unwrap();
        let e = r.f32s("cache", 1000).err().unwrap();
        assert!(e.to_string().contains("at most 1000"), "{e}");
    }
}
