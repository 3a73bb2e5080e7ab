//! A small, explicit byte form for what must be restored in another instance or process:
//! little-endian fields in a fixed order, no pointers. The integrators write their memory
//! with it; whoever frames the bytes (a header, a version, a checksum) does so above.

/// Writes a field named, in the layout, by the expression it is written from:
/// `put!(w.f64(self.time))` is `w.named("self.time").f64(self.time)`.
#[macro_export]
macro_rules! put {
    ($w:ident . $kind:ident ( $($value:tt)* )) => {
        $w.named(stringify!($($value)*)).$kind($($value)*)
    };
}

pub use crate::put;

/// Appends fields to a payload.
pub struct Writer {
    bytes: Vec<u8>,
    /// A hash of the kinds of the fields written, in order: the payload's layout without
    /// its values, which the one who frames the bytes can pin to a version of its format.
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

    /// Names the next field in the layout (not in the bytes): with every field named, two
    /// fields of one kind swapped, or one written from another value, change the layout
    /// as a field of another kind does. [`put!`](crate::put) names a field by the
    /// expression it is written from.
    pub fn named(&mut self, name: &str) -> &mut Self {
        for byte in name.bytes().chain([0]) {
            self.field(byte);
        }
        self
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

    /// The bytes written.
    pub fn into_bytes(self) -> Vec<u8> {
        self.bytes
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
    /// A reader over `bytes`, from their first field.
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes }
    }

    fn take<const K: usize>(&mut self) -> Result<[u8; K], FormatError> {
        if self.bytes.len() < K {
            return Err(FormatError("the bytes end early".into()));
        }
        let (head, rest) = self.bytes.split_at(K);
        self.bytes = rest;
        Ok(head.try_into().expect("K bytes"))
    }

    /// A number: every one written is finite (an absent value has a flag of its own), so a
    /// non-finite one means the bytes changed after they were written.
    pub fn f64(&mut self) -> Result<f64, FormatError> {
        let value = f64::from_le_bytes(self.take()?);
        if !value.is_finite() {
            return Err(FormatError(format!(
                "a non-finite number ({value}) where every number is finite"
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
                "{} unexpected bytes after the last field",
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

    #[test]
    fn round_trip() {
        let mut w = Writer::default();
        w.f64(1.5);
        w.u64(7);
        w.bool(true);
        w.f64s(&[-1e300, -0.0]);
        let bytes = w.into_bytes();
        let mut r = Reader::new(&bytes);
        assert_eq!(r.f64().unwrap(), 1.5);
        assert_eq!(r.u64().unwrap(), 7);
        assert!(r.bool().unwrap());
        let [a, b] = r.f64s::<2>().unwrap();
        assert_eq!(a, -1e300);
        assert!(b == 0.0 && b.is_sign_negative());
        r.finish().unwrap();
    }

    #[test]
    fn a_non_finite_number_is_refused() {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut w = Writer::default();
            w.f64(bad);
            let bytes = w.into_bytes();
            assert!(
                Reader::new(&bytes)
                    .f64()
                    .unwrap_err()
                    .0
                    .contains("non-finite"),
                "{bad}"
            );
        }
    }

    #[test]
    fn reading_past_the_end_or_short_of_it_is_an_error() {
        let mut w = Writer::default();
        w.u8(3);
        let bytes = w.into_bytes();
        assert!(Reader::new(&bytes).bool().is_err());
        assert!(Reader::new(&bytes).f64().is_err());
        assert!(Reader::new(&bytes)
            .finish()
            .unwrap_err()
            .0
            .contains("1 unexpected"));
    }

    #[test]
    fn the_layout_is_the_kinds_of_the_fields_in_order() {
        let layout = |kinds: &[u8]| {
            let mut w = Writer::default();
            for &k in kinds {
                match k {
                    b'f' => w.f64(0.0),
                    b'u' => w.u64(0),
                    _ => w.u8(0),
                }
            }
            w.layout()
        };
        assert_eq!(layout(b"fub"), layout(b"fub"));
        assert_ne!(layout(b"fub"), layout(b"ufb"));
    }

    #[test]
    fn two_named_fields_of_one_kind_swapped_change_the_layout() {
        let (time, speed) = (1.0, 2.0);
        let mut written = Writer::default();
        crate::put!(written.f64(time));
        crate::put!(written.f64(speed));
        let mut swapped = Writer::default();
        crate::put!(swapped.f64(speed));
        crate::put!(swapped.f64(time));
        let mut unnamed = Writer::default();
        unnamed.f64(time);
        unnamed.f64(speed);
        assert_ne!(written.layout(), swapped.layout());
        assert_ne!(written.layout(), unnamed.layout());
        assert_eq!(written.into_bytes(), {
            let mut same = Writer::default();
            crate::put!(same.f64(time));
            crate::put!(same.f64(speed));
            same.into_bytes()
        });
    }
}
