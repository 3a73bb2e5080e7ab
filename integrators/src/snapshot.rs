//! A small, explicit byte format for serialized FMU states: little-endian fields in a fixed
//! order, behind a header (magic, version, interface hash, length) and followed by a
//! checksum. Position-independent (no pointers), so a state restores in another instance
//! or process; a truncated, corrupted or foreign buffer is refused with a reason.

const MAGIC: &[u8; 8] = b"CYCMSTAT";
/// Bump when the layout of the payload changes.
pub const FORMAT_VERSION: u32 = 18;
const HEADER: usize = 8 + 4 + 8 + 8;

/// Appends fields to a payload.
pub struct Writer {
    bytes: Vec<u8>,
    /// A hash of the kinds of the fields written, in order: the payload's layout without
    /// its values, which a test pins to [`FORMAT_VERSION`].
    layout: u64,
}

impl Default for Writer {
    fn default() -> Self {
        Self {
            bytes: Vec::new(),
            layout: FNV_OFFSET,
        }
    }
}

impl Writer {
    fn field(&mut self, kind: u8) {
        self.layout = (self.layout ^ u64::from(kind)).wrapping_mul(FNV_PRIME);
    }

    pub fn f64(&mut self, value: f64) {
        self.field(b'f');
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    pub fn f64s(&mut self, values: &[f64]) {
        values.iter().for_each(|v| self.f64(*v));
    }

    pub fn u64(&mut self, value: u64) {
        self.field(b'u');
        self.bytes.extend_from_slice(&value.to_le_bytes());
    }

    pub fn u8(&mut self, value: u8) {
        self.field(b'b');
        self.bytes.push(value);
    }

    /// The layout of what was written so far: the kinds of its fields, in order.
    pub fn layout(&self) -> u64 {
        self.layout
    }

    pub fn bool(&mut self, value: bool) {
        self.u8(value as u8);
    }

    /// The framed buffer: header, payload, checksum.
    pub fn finish(self, interface: u64) -> Vec<u8> {
        let mut out = Vec::with_capacity(HEADER + self.bytes.len() + 8);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&interface.to_le_bytes());
        out.extend_from_slice(&(self.bytes.len() as u64).to_le_bytes());
        out.extend_from_slice(&self.bytes);
        out.extend_from_slice(&fnv1a_64(&self.bytes).to_le_bytes());
        out
    }
}

/// Reads fields back, in the order they were written.
#[derive(Debug)]
pub struct Reader<'a> {
    bytes: &'a [u8],
}

/// Why a buffer cannot be restored.
#[derive(Debug, PartialEq)]
pub struct FormatError(pub String);

impl std::fmt::Display for FormatError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl<'a> Reader<'a> {
    /// Check the frame and return a reader over the payload.
    pub fn open(buffer: &'a [u8], interface: u64) -> Result<Self, FormatError> {
        let fail = |why: &str| Err(FormatError(why.to_string()));
        if buffer.len() < HEADER + 8 {
            return fail("the buffer is shorter than a serialized state's header");
        }
        if &buffer[..8] != MAGIC {
            return fail("the buffer is not a serialized state of this FMU (wrong magic number)");
        }
        let version = u32::from_le_bytes(buffer[8..12].try_into().expect("4 bytes"));
        if version != FORMAT_VERSION {
            return Err(FormatError(format!(
                "serialized state format version {version}; this binary reads version {FORMAT_VERSION}"
            )));
        }
        if u64::from_le_bytes(buffer[12..20].try_into().expect("8 bytes")) != interface {
            return fail("the serialized state comes from an FMU with another interface (GUID)");
        }
        let length = u64::from_le_bytes(buffer[20..28].try_into().expect("8 bytes"));
        if length != (buffer.len() - HEADER - 8) as u64 {
            return Err(FormatError(format!(
                "the buffer holds {} payload bytes, the header announces {length}: truncated or padded",
                buffer.len() - HEADER - 8
            )));
        }
        let payload = &buffer[HEADER..buffer.len() - 8];
        let checksum = u64::from_le_bytes(buffer[buffer.len() - 8..].try_into().expect("8 bytes"));
        if checksum != fnv1a_64(payload) {
            return fail("the serialized state is corrupted (checksum mismatch)");
        }
        Ok(Self { bytes: payload })
    }

    fn take<const K: usize>(&mut self) -> Result<[u8; K], FormatError> {
        if self.bytes.len() < K {
            return Err(FormatError("the serialized state ends early".into()));
        }
        let (head, rest) = self.bytes.split_at(K);
        self.bytes = rest;
        Ok(head.try_into().expect("K bytes"))
    }

    /// A number of the state: every one is finite (an absent value has a flag of its
    /// own), so a non-finite one means a buffer changed after it was written.
    pub fn f64(&mut self) -> Result<f64, FormatError> {
        let value = f64::from_le_bytes(self.take()?);
        if !value.is_finite() {
            return Err(FormatError(format!(
                "invalid serialized state: a non-finite number ({value}) where every number is finite"
            )));
        }
        Ok(value)
    }

    pub fn f64s<const K: usize>(&mut self) -> Result<[f64; K], FormatError> {
        let mut values = [0.0; K];
        for v in values.iter_mut() {
            *v = self.f64()?;
        }
        Ok(values)
    }

    pub fn u64(&mut self) -> Result<u64, FormatError> {
        Ok(u64::from_le_bytes(self.take()?))
    }

    pub fn u8(&mut self) -> Result<u8, FormatError> {
        Ok(self.take::<1>()?[0])
    }

    pub fn bool(&mut self) -> Result<bool, FormatError> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            other => Err(FormatError(format!("invalid flag byte {other}"))),
        }
    }

    /// Every field has been read: trailing bytes mean a layout mismatch.
    pub fn finish(self) -> Result<(), FormatError> {
        if self.bytes.is_empty() {
            Ok(())
        } else {
            Err(FormatError(format!(
                "{} unexpected bytes after the serialized state",
                self.bytes.len()
            )))
        }
    }
}

/// Whether two arrays hold the same numbers bit for bit: how restored values are checked
/// against their recomputation (== would take −0 for 0 and refuse a NaN for itself).
pub fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

pub fn fnv1a_64(bytes: &[u8]) -> u64 {
    bytes
        .iter()
        .fold(FNV_OFFSET, |h, &b| (h ^ b as u64).wrapping_mul(FNV_PRIME))
}

/// FNV-1a's 64-bit offset basis and prime.
const FNV_OFFSET: u64 = 0xcbf29ce484222325;
const FNV_PRIME: u64 = 0x100000001b3;

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Vec<u8> {
        let mut w = Writer::default();
        w.f64(1.5);
        w.u64(7);
        w.bool(true);
        w.f64s(&[-1e300, -0.0]);
        w.finish(42)
    }

    #[test]
    fn round_trip() {
        let buffer = sample();
        let mut r = Reader::open(&buffer, 42).unwrap();
        assert_eq!(r.f64().unwrap(), 1.5);
        assert_eq!(r.u64().unwrap(), 7);
        assert!(r.bool().unwrap());
        let [a, b] = r.f64s::<2>().unwrap();
        assert_eq!(a, -1e300);
        assert!(b == 0.0 && b.is_sign_negative());
        r.finish().unwrap();
    }

    #[test]
    fn a_non_finite_number_is_refused_even_with_a_valid_checksum() {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut w = Writer::default();
            w.f64(bad);
            let buffer = w.finish(42);
            let mut r = Reader::open(&buffer, 42).unwrap();
            assert!(r.f64().unwrap_err().0.contains("non-finite"), "{bad}");
        }
    }

    #[test]
    fn truncated_corrupt_and_foreign_buffers_are_refused() {
        let buffer = sample();
        for cut in [0, 5, 27, buffer.len() - 1] {
            assert!(Reader::open(&buffer[..cut], 42).is_err(), "cut at {cut}");
        }
        let mut corrupt = buffer.clone();
        corrupt[30] ^= 1;
        assert!(Reader::open(&corrupt, 42)
            .unwrap_err()
            .0
            .contains("corrupted"));
        assert!(Reader::open(&buffer, 43)
            .unwrap_err()
            .0
            .contains("interface"));
        let mut other = buffer.clone();
        other[0] = b'X';
        assert!(Reader::open(&other, 42).unwrap_err().0.contains("magic"));
        let mut version = buffer;
        version[8] = (FORMAT_VERSION + 1) as u8;
        assert!(Reader::open(&version, 42)
            .unwrap_err()
            .0
            .contains("version"));
    }

    #[test]
    fn reading_past_the_end_is_an_error() {
        let mut w = Writer::default();
        w.u8(3);
        let buffer = w.finish(1);
        let mut r = Reader::open(&buffer, 1).unwrap();
        assert!(r.bool().is_err());
        let mut r = Reader::open(&buffer, 1).unwrap();
        assert!(r.f64().is_err());
    }
}
