//! Sealed snapshots: a snapshot under an HMAC-SHA-256 tag made with a key the caller holds, for
//! snapshot stores that others can write (a service's snapshot folder, a game's save files).
//!
//! A snapshot's CRC-32 detects accidents; whoever can write the store can recompute it. Restore
//! checks every field (`docs/SNAPSHOTS.md`), so an edited snapshot cannot harm the process, but
//! it can still be another stream than the one saved: another client's, or an older one put
//! back. A sealed snapshot carries a tag that only a holder of the key can make. The tag is
//! checked, in constant time, before a byte of the snapshot inside is read.
//!
//! Layout, little-endian:
//!
//! | bytes | what |
//! |---|---|
//! | 8 | magic `TRPSEAL\0` |
//! | 4 | sealing version ([`SEALED_VERSION`]) |
//! | 32 | HMAC-SHA-256 under the key, of the version's 4 bytes then the snapshot |
//! | n | the snapshot, as `Session::snapshot` wrote it |

use hmac::{Hmac, Mac};
use sha2::Sha256;

use crate::shared::error::{Error, Result};
use crate::shared::snapshot::{bad, MAGIC, SEALED_MAGIC};
/// The sealing layout written; a reader refuses any other.
pub const SEALED_VERSION: u32 = 1;
/// The shortest key accepted: 128 bits, below which a key can be guessed.
pub const MIN_KEY_BYTES: usize = 16;
/// Bytes before the snapshot: magic, version, tag.
const HEADER_BYTES: usize = 8 + 4 + 32;

/// The MAC of `key`, fed the version; a key shorter than [`MIN_KEY_BYTES`] is refused.
fn mac(key: &[u8]) -> Result<Hmac<Sha256>> {
    if key.len() < MIN_KEY_BYTES {
        return Err(Error::InvalidInput(format!(
            "a snapshot key is at least {MIN_KEY_BYTES} bytes, got {}",
            key.len()
        )));
    }
    let mut mac = Hmac::<Sha256>::new_from_slice(key).expect("HMAC takes keys of any length");
    mac.update(&SEALED_VERSION.to_le_bytes());
    Ok(mac)
}

/// `snapshot` sealed under `key`. Only a snapshot is sealed (its magic is checked, its contents
/// are checked when it is restored).
pub fn seal(snapshot: &[u8], key: &[u8]) -> Result<Vec<u8>> {
    let mut mac = mac(key)?;
    if !snapshot.starts_with(&MAGIC) {
        return Err(bad(if snapshot.starts_with(&SEALED_MAGIC) {
            "already sealed"
        } else {
            "not a troupe snapshot (no TRPSNAP magic): only snapshots are sealed"
        }));
    }
    mac.update(snapshot);
    let mut sealed = Vec::with_capacity(HEADER_BYTES + snapshot.len());
    sealed.extend_from_slice(&SEALED_MAGIC);
    sealed.extend_from_slice(&SEALED_VERSION.to_le_bytes());
    sealed.extend_from_slice(&mac.finalize().into_bytes());
    sealed.extend_from_slice(snapshot);
    Ok(sealed)
}

/// The snapshot inside `sealed`, once its tag is shown to be `key`'s; refused, naming why, when
/// it is not a sealed snapshot, is of another sealing version, or its tag does not match (another
/// key sealed it, or a byte of it changed).
pub fn open<'a>(sealed: &'a [u8], key: &[u8]) -> Result<&'a [u8]> {
    let mut mac = mac(key)?;
    if sealed.starts_with(&MAGIC) {
        return Err(bad(
            "not sealed: it was saved without a key, and a sealed restore takes only sealed ones",
        ));
    }
    if !sealed.starts_with(&SEALED_MAGIC) {
        return Err(bad("not a sealed troupe snapshot (no TRPSEAL magic)"));
    }
    if sealed.len() < HEADER_BYTES {
        return Err(bad(format!(
            "a sealed snapshot of {} bytes is shorter than its {HEADER_BYTES}-byte header",
            sealed.len()
        )));
    }
    let version = u32::from_le_bytes(sealed[8..12].try_into().expect("4 bytes"));
    if version != SEALED_VERSION {
        return Err(bad(format!(
            "sealing version {version}; this troupe reads version {SEALED_VERSION}"
        )));
    }
    let (tag, snapshot) = sealed[12..].split_at(32);
    mac.update(snapshot);
    mac.verify_slice(tag).map_err(|_| {
        bad("its seal does not match this key: another key sealed it, or its bytes were changed")
    })?;
    Ok(snapshot)
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: &[u8] = b"sixteen byte key";

    fn snapshot() -> Vec<u8> {
        let mut bytes = MAGIC.to_vec();
        bytes.extend_from_slice(b"the rest of a snapshot");
        bytes
    }

    #[test]
    fn a_sealed_snapshot_opens_with_its_key_only_and_unchanged() {
        let sealed = seal(&snapshot(), KEY).unwrap();
        assert_eq!(open(&sealed, KEY).unwrap(), snapshot());
        let refused = |bytes: &[u8], key: &[u8]| open(bytes, key).unwrap_err().to_string();
        assert!(refused(&sealed, b"another 16-byte key").contains("does not match this key"));
        for i in [0, 9, 12, 40, sealed.len() - 1] {
            let mut edited = sealed.clone();
            edited[i] ^= 1;
            assert!(open(&edited, KEY).is_err(), "byte {i} flipped");
        }
        assert!(refused(&sealed[..sealed.len() - 1], KEY).contains("does not match"));
        assert!(refused(&sealed[..20], KEY).contains("shorter than its 44-byte header"));
        assert!(refused(&snapshot(), KEY).contains("not sealed"));
        assert!(refused(b"hello", KEY).contains("no TRPSEAL magic"));
        assert!(refused(&sealed, b"short").contains("at least 16 bytes"));
        let mut later = sealed.clone();
        later[8] = 2;
        assert!(refused(&later, KEY).contains("sealing version 2"));
        assert!(seal(b"not one", KEY).is_err());
        assert!(seal(&sealed, KEY)
            .unwrap_err()
            .to_string()
            .contains("already sealed"));
    }
}
