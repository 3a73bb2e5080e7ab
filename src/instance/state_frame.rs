//! The frame of a serialized FMU state: magic, format version, the interface's hash, the
//! payload's length, the payload, and a checksum. A truncated, corrupted or foreign buffer
//! is refused with a reason before a field of it is read.

use crate::description::identity;
use integrators::bytes::{fnv1a_64, FormatError, Reader};

const MAGIC: &[u8; 8] = b"CYCMSTAT";
/// Raise when the payload's layout changes (`tests/state_layout.rs` pins the two
/// together), so that an old buffer is refused by its version rather than misread.
pub const FORMAT_VERSION: u32 = 20;
/// The header's bytes: magic, version, interface hash, payload length.
pub const HEADER: usize = 8 + 4 + 16 + 8;
const CHECKSUM: usize = 8;

/// `payload` framed: header, payload, checksum.
pub(super) fn frame(payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER + payload.len() + CHECKSUM);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&identity().to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(payload);
    out.extend_from_slice(&fnv1a_64(payload).to_le_bytes());
    out
}

/// A reader over the payload of `buffer`, once its frame is checked.
pub(super) fn open(buffer: &[u8]) -> Result<Reader<'_>, FormatError> {
    let fail = |why: String| Err(FormatError(why));
    if buffer.len() < HEADER + CHECKSUM {
        return fail("the buffer is shorter than a serialized state's header".into());
    }
    let (header, rest) = buffer.split_at(HEADER);
    let (payload, checksum) = rest.split_at(rest.len() - CHECKSUM);
    if &header[..8] != MAGIC {
        return fail(
            "the buffer is not a serialized state of this FMU (wrong magic number)".into(),
        );
    }
    let version = u32::from_le_bytes(header[8..12].try_into().expect("4 bytes"));
    if version != FORMAT_VERSION {
        return fail(format!(
            "serialized state format version {version}; this binary reads version {FORMAT_VERSION}"
        ));
    }
    if u128::from_le_bytes(header[12..28].try_into().expect("16 bytes")) != identity() {
        return fail("the serialized state comes from an FMU with another interface".into());
    }
    let length = u64::from_le_bytes(header[28..36].try_into().expect("8 bytes"));
    if length != payload.len() as u64 {
        return fail(format!(
            "the buffer holds {} payload bytes, the header announces {length}: truncated or padded",
            payload.len()
        ));
    }
    if u64::from_le_bytes(checksum.try_into().expect("8 bytes")) != fnv1a_64(payload) {
        return fail("the serialized state is corrupted (checksum mismatch)".into());
    }
    Ok(Reader::new(payload))
}

#[cfg(test)]
mod tests {
    use super::*;
    use integrators::bytes::Writer;

    fn sample() -> Vec<u8> {
        let mut w = Writer::default();
        w.f64(1.5);
        w.u64(7);
        frame(&w.into_bytes())
    }

    #[test]
    fn a_framed_payload_reads_back() {
        let buffer = sample();
        let mut r = open(&buffer).unwrap();
        assert_eq!(r.f64().unwrap(), 1.5);
        assert_eq!(r.u64().unwrap(), 7);
        r.finish().unwrap();
    }

    #[test]
    fn truncated_corrupt_and_foreign_buffers_are_refused() {
        let buffer = sample();
        let why = |b: &[u8]| open(b).unwrap_err().0;
        for cut in [0, 5, HEADER, buffer.len() - 1] {
            assert!(open(&buffer[..cut]).is_err(), "cut at {cut}");
        }
        let mut corrupt = buffer.clone();
        corrupt[HEADER + 2] ^= 1;
        assert!(why(&corrupt).contains("corrupted"));
        let mut foreign = buffer.clone();
        foreign[12] ^= 1;
        assert!(why(&foreign).contains("another interface"));
        let mut other = buffer.clone();
        other[0] = b'X';
        assert!(why(&other).contains("magic"));
        let mut version = buffer;
        version[8] = (FORMAT_VERSION + 1) as u8;
        assert!(why(&version).contains("version"));
    }
}
