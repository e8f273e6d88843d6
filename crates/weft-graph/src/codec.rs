//! Little-endian byte writing and bounds-checked reading, for the byte codecs of port types
//! and the disk checkpoints of stateful nodes. A reader never panics on short or damaged
//! input: every read says what was missing.

/// Appends values to a byte buffer.
#[derive(Default)]
pub struct Writer {
    /// The bytes written so far.
    pub buf: Vec<u8>,
}

impl Writer {
    /// An empty writer.
    pub fn new() -> Self {
        Self::default()
    }
    /// A `u64`.
    pub fn u64(&mut self, x: u64) -> &mut Self {
        self.buf.extend_from_slice(&x.to_le_bytes());
        self
    }
    /// An `f64`, bit for bit.
    pub fn f64(&mut self, x: f64) -> &mut Self {
        self.buf.extend_from_slice(&x.to_le_bytes());
        self
    }
    /// A length-prefixed run of `f64`s.
    pub fn f64s(&mut self, xs: &[f64]) -> &mut Self {
        self.u64(xs.len() as u64);
        self.buf.reserve(8 * xs.len());
        for x in xs {
            self.buf.extend_from_slice(&x.to_le_bytes());
        }
        self
    }
    /// A length-prefixed run of 3-vectors.
    pub fn vec3s(&mut self, xs: &[[f64; 3]]) -> &mut Self {
        self.u64(xs.len() as u64);
        self.buf.reserve(24 * xs.len());
        for x in xs {
            for c in x {
                self.buf.extend_from_slice(&c.to_le_bytes());
            }
        }
        self
    }
    /// Length-prefixed bytes.
    pub fn bytes(&mut self, b: &[u8]) -> &mut Self {
        self.u64(b.len() as u64);
        self.buf.extend_from_slice(b);
        self
    }
    /// The buffer.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Reads what a [`Writer`] wrote.
pub struct Reader<'a> {
    b: &'a [u8],
}

impl<'a> Reader<'a> {
    /// A reader over `b`.
    pub fn new(b: &'a [u8]) -> Self {
        Reader { b }
    }
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], String> {
        if self.b.len() < n {
            return Err(format!(
                "truncated: {what} needs {n} bytes, {} left",
                self.b.len()
            ));
        }
        let (h, t) = self.b.split_at(n);
        self.b = t;
        Ok(h)
    }
    /// A `u64`.
    pub fn u64(&mut self) -> Result<u64, String> {
        let b = self.take(8, "an integer")?;
        Ok(u64::from_le_bytes(b.try_into().map_err(|_| "8 bytes")?))
    }
    /// An `f64`.
    pub fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_bits(self.u64()?))
    }
    fn len(&mut self, unit: usize, what: &str) -> Result<usize, String> {
        let n = self.u64()?;
        // A damaged length must not allocate: it cannot exceed what is left.
        match usize::try_from(n) {
            Ok(n) if n.checked_mul(unit).is_some_and(|b| b <= self.b.len()) => Ok(n),
            _ => Err(format!(
                "{what}: length {n} exceeds the {} bytes left",
                self.b.len()
            )),
        }
    }
    /// A length-prefixed run of `f64`s.
    pub fn f64s(&mut self) -> Result<Vec<f64>, String> {
        let n = self.len(8, "numbers")?;
        let b = self.take(8 * n, "numbers")?;
        Ok(b.chunks_exact(8)
            .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
            .collect())
    }
    /// A length-prefixed run of 3-vectors.
    pub fn vec3s(&mut self) -> Result<Vec<[f64; 3]>, String> {
        let n = self.len(24, "vectors")?;
        let b = self.take(24 * n, "vectors")?;
        Ok(b.chunks_exact(24)
            .map(|c| {
                let f = |k: usize| {
                    f64::from_le_bytes([
                        c[k],
                        c[k + 1],
                        c[k + 2],
                        c[k + 3],
                        c[k + 4],
                        c[k + 5],
                        c[k + 6],
                        c[k + 7],
                    ])
                };
                [f(0), f(8), f(16)]
            })
            .collect())
    }
    /// Length-prefixed bytes.
    pub fn bytes(&mut self) -> Result<&'a [u8], String> {
        let n = self.len(1, "bytes")?;
        self.take(n, "bytes")
    }
    /// Fails unless everything was read.
    pub fn end(&self) -> Result<(), String> {
        if self.b.is_empty() {
            Ok(())
        } else {
            Err(format!("{} bytes left over", self.b.len()))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_damage() {
        let mut w = Writer::new();
        w.u64(7)
            .f64(-0.0)
            .f64s(&[1.5, f64::MIN_POSITIVE])
            .vec3s(&[[1.0, 2.0, 3.0]])
            .bytes(b"ab");
        let b = w.finish();
        let mut r = Reader::new(&b);
        assert_eq!(r.u64().unwrap(), 7);
        assert_eq!(r.f64().unwrap().to_bits(), (-0.0f64).to_bits());
        assert_eq!(r.f64s().unwrap(), vec![1.5, f64::MIN_POSITIVE]);
        assert_eq!(r.vec3s().unwrap(), vec![[1.0, 2.0, 3.0]]);
        assert_eq!(r.bytes().unwrap(), b"ab");
        r.end().unwrap();
        // Every truncation is an error, never a panic or a huge allocation.
        for cut in 0..b.len() {
            let mut r = Reader::new(&b[..cut]);
            let ok = r.u64().is_ok()
                && r.f64().is_ok()
                && r.f64s().is_ok()
                && r.vec3s().is_ok()
                && r.bytes().is_ok();
            assert!(!ok, "cut at {cut} read through");
        }
        let mut huge = Writer::new();
        huge.u64(u64::MAX);
        assert!(Reader::new(&huge.finish()).f64s().is_err());
    }
}
