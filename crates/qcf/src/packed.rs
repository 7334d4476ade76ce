//! The container's packed streams (DESIGN section 16, "The container"): bits written and read
//! low first, Rice codes, a curve's control-point codes as residuals from a linear prediction
//! and its knots as deltas. Each stream is read one value after another, every value checked:
//! the container's reader reads them whole, the runtime decoder as its cursors step.

/// Control points per block of Rice parameters.
pub(crate) const BLOCK: usize = 16;

/// Bits of a block's Rice parameter.
pub(crate) const RICE_BITS: u32 = 5;

/// The largest Rice parameter.
pub(crate) const MOST_RICE: u32 = (1 << RICE_BITS) - 1;

/// Each code's prediction from the two points before it: the line through them (a smooth
/// curve's control points lie nearly on one). The first point is stored whole, and the second
/// is predicted by the first alone (`two_back` the same point as `last`).
pub(crate) fn predicted(two_back: &[u32; 3], last: &[u32; 3], c: usize) -> i64 {
    2 * i64::from(last[c]) - i64::from(two_back[c])
}

/// Bits of `z` as a Rice code of parameter `k`: the quotient `z >> k` in unary (that many
/// one bits and a zero), then the low `k` bits.
pub(crate) fn rice_bits(z: u64, k: u32) -> u64 {
    (z >> k) + 1 + u64::from(k)
}

/// The Rice parameter (0 to [`MOST_RICE`]) that codes `values` in the fewest bits.
pub(crate) fn rice_parameter(values: impl Iterator<Item = u64> + Clone) -> u32 {
    (0..=MOST_RICE).min_by_key(|&k| values.clone().map(|z| rice_bits(z, k)).sum::<u64>()).unwrap_or(0)
}

/// How a curve's knots and codes are packed: as the container stores them, or as the runtime
/// decoder reads them ([`super::decoder`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Packing {
    /// Rice codes: the fewest bytes, read one after another.
    Rice,
    /// A fixed width per curve's knots and per block's component: each value's place known
    /// before the values ahead of it are read.
    Fixed,
}

/// Codes packed low bit first: the first point's at `bits` each, then per block of [`BLOCK`]
/// points each component's parameter ([`RICE_BITS`]) and the points' zigzagged residuals from
/// [`predicted`]. As Rice codes ([`Packing::Rice`], the container's: the parameter of fewest
/// bits for the block; residuals are about Laplacian, which Rice codes fit: 4-7% fewer bytes
/// than one width per block, for about twice the time to unpack, a code's length known only
/// once it is read), or at the block's widest residual's width ([`Packing::Fixed`], the
/// runtime's, [`FixedCodes`]).
pub(crate) fn pack_codes(codes: &[[u32; 3]], bits: u32, packing: Packing) -> Vec<u8> {
    let mut out = BitWriter::default();
    let Some(first) = codes.first() else { return out.finish() };
    first.iter().for_each(|&c| out.push(u64::from(c), bits));
    for block in (1..codes.len()).step_by(BLOCK) {
        let points = block..(block + BLOCK).min(codes.len());
        let parameters: [u32; 3] = std::array::from_fn(|c| {
            let residuals = points.clone().map(|i| residual(codes, i, c));
            match packing {
                Packing::Rice => rice_parameter(residuals),
                Packing::Fixed => width_of(residuals),
            }
        });
        parameters.iter().for_each(|&p| out.push(u64::from(p), RICE_BITS));
        for i in points {
            for (c, &p) in parameters.iter().enumerate() {
                match packing {
                    Packing::Rice => out.rice(residual(codes, i, c), p),
                    Packing::Fixed => out.push(residual(codes, i, c), p),
                }
            }
        }
    }
    out.finish()
}

/// Why packed control-point codes do not decode within their width.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub(crate) enum CodeFault {
    /// The bytes end inside a point.
    #[error("the packed codes end in control point {0}")]
    End(usize),
    /// A code outside its width.
    #[error("control point {point} component {component} decodes to {value}, outside {bits} bits")]
    Outside { point: usize, component: usize, value: i64, bits: u32 },
    /// A residual's unary run longer than any residual of the width.
    #[error("control point {point} component {component}: a residual's quotient {quotient} is larger than any of {bits} bits")]
    Runaway { point: usize, component: usize, quotient: u64, bits: u32 },
}

/// A curve's control-point codes ([`pack_codes`]) read one point after another, each checked to
/// lie within the width.
#[derive(Clone, Debug)]
pub(crate) struct Codes<'a> {
    bits: BitReader<'a>,
    width: u32,
    /// The next point's index.
    next: usize,
    /// The current block's Rice parameters.
    ks: [u32; 3],
    /// The two points before the next, kept in the stream so that they stay in registers.
    two_back: [u32; 3],
    last: [u32; 3],
}

impl<'a> Codes<'a> {
    pub(crate) fn new(packed: &'a [u8], width: u32) -> Self {
        Self { bits: BitReader::new(packed), width, next: 0, ks: [0; 3], two_back: [0; 3], last: [0; 3] }
    }

    /// The next point's codes.
    #[inline(always)]
    pub(crate) fn next(&mut self) -> Result<[u32; 3], CodeFault> {
        let (i, bits) = (self.next, self.width);
        let most = (1i64 << bits) - 1;
        let outside = |component: usize, value: i64| CodeFault::Outside { point: i, component, value, bits };
        let mut point = [0u32; 3];
        if i == 0 {
            // The first point whole.
            for (c, code) in point.iter_mut().enumerate() {
                let value = self.bits.take(bits).ok_or(CodeFault::End(0))? as i64;
                if value > most {
                    return Err(outside(c, value));
                }
                *code = value as u32;
            }
            self.last = point;
        } else {
            if (i - 1) % BLOCK == 0 {
                for k in &mut self.ks {
                    *k = self.bits.take(RICE_BITS).ok_or(CodeFault::End(i))? as u32;
                }
            }
            // A residual of a code within `bits` from a prediction within `bits + 1`, zigzagged.
            let most_zigzag = 1u64 << (bits + 2);
            for (c, code) in point.iter_mut().enumerate() {
                let k = self.ks[c];
                let (quotient, low) = self.bits.rice(k).ok_or(CodeFault::End(i))?;
                if quotient > most_zigzag >> k {
                    return Err(CodeFault::Runaway { point: i, component: c, quotient, bits });
                }
                let r = unzigzag((quotient << k) | low);
                let value = predicted(&self.two_back, &self.last, c).wrapping_add(r);
                if !(0..=most).contains(&value) {
                    return Err(outside(c, value));
                }
                *code = value as u32;
            }
        }
        // The second point is predicted by the first alone.
        self.two_back = if i == 0 { point } else { self.last };
        self.last = point;
        self.next += 1;
        Ok(point)
    }
}

/// `n` points' codes of [`pack_codes`], each checked to lie within `bits`.
pub(crate) fn unpack_codes(packed: &[u8], n: usize, bits: u32) -> Result<Vec<[u32; 3]>, CodeFault> {
    let mut codes = Codes::new(packed, bits);
    (0..n).map(|_| codes.next()).collect()
}

/// Why a knot read is not one of the places the curve may have.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub(crate) enum KnotFault {
    /// The bytes end first.
    #[error("the packed knots end before it")]
    End,
    /// A delta's unary run longer than any delta of the places.
    #[error("a delta's quotient {0} is past the timeline")]
    Runaway(u64),
    /// A knot outside the timeline's interior.
    #[error("{unit} {at} is not inside 1..{last}")]
    Outside { unit: &'static str, at: u64, last: usize },
    /// A knot repeated more often than the curve's order allows.
    #[error("{unit} {at} repeated {} times; at most {most}", most + 1)]
    Repeated { unit: &'static str, at: u64, most: usize },
}

/// Where a curve's knots may lie: strictly inside places `0..last` (a cubic's samples, or keys),
/// each taken at most `repeats` times, consecutive ones at least `least` apart.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Places {
    pub(crate) unit: &'static str,
    pub(crate) last: usize,
    pub(crate) repeats: usize,
    pub(crate) least: u32,
}

impl Places {
    /// The most knots the places take: every interior place, each `repeats` times.
    pub(crate) fn most(&self) -> usize {
        self.last.saturating_sub(1) * self.repeats
    }
}

/// A curve's knots ([`Writer::knots`](super::Writer)) read one after another, each checked to be
/// one of its [`Places`].
#[derive(Clone, Debug)]
pub(crate) struct Knots<'a> {
    bits: BitReader<'a>,
    /// The deltas' Rice parameter.
    k: u32,
    places: Places,
    /// The largest quotient a delta within the places has.
    most_quotient: u64,
    /// The knot before the next (0 before the first) and how many times in a row it was read.
    previous: u64,
    run: usize,
}

impl<'a> Knots<'a> {
    pub(crate) fn new(packed: &'a [u8], k: u32, places: Places) -> Self {
        let most_quotient = (places.most() as u64 + 1) >> k;
        Self { bits: BitReader::new(packed), k, places, most_quotient, previous: 0, run: 0 }
    }

    /// The next knot's place.
    #[inline(always)]
    pub(crate) fn next(&mut self) -> Result<u32, KnotFault> {
        let (quotient, low) = self.bits.rice(self.k).ok_or(KnotFault::End)?;
        // No delta reaches past every interior place: a longer run is named, not shifted.
        if quotient > self.most_quotient {
            return Err(KnotFault::Runaway(quotient));
        }
        let Places { unit, last, repeats, least } = self.places;
        let at = self.previous + ((quotient << self.k) | low) + u64::from(least);
        if at == 0 || at >= last as u64 {
            return Err(KnotFault::Outside { unit, at, last });
        }
        self.run = if at == self.previous { self.run + 1 } else { 1 };
        if self.run > repeats {
            return Err(KnotFault::Repeated { unit, at, most: repeats });
        }
        self.previous = at;
        Ok(at as u32)
    }

    /// The bytes the knots read so far began in.
    pub(crate) fn bytes_read(&self) -> usize {
        self.bits.bytes_read()
    }
}

/// The fewest bits that hold every one of `values`.
pub(crate) fn width_of(values: impl Iterator<Item = u64>) -> u32 {
    64 - values.fold(0, |all, v| all | v).leading_zeros()
}

/// Point `i`'s (at least 1) component `c` less its [`predicted`] value, zigzagged.
fn residual(codes: &[[u32; 3]], i: usize, c: usize) -> u64 {
    zigzag(i64::from(codes[i][c]) - predicted(&codes[i - 1 - usize::from(i >= 2)], &codes[i - 1], c))
}

/// A residual zigzagged: `r >= 0` as `2r`, else `-2r - 1`.
fn zigzag(r: i64) -> u64 {
    ((r << 1) ^ (r >> 63)) as u64
}

/// [`zigzag`] undone.
#[inline(always)]
fn unzigzag(z: u64) -> i64 {
    (z >> 1) as i64 ^ -((z & 1) as i64)
}

/// `width` (at most 32) bits at bit `at` of `bytes`, low bit first: one unaligned read of the 8
/// bytes there (the runtime clips end in 8 zero bytes), 0 past the end.
#[inline(always)]
pub(crate) fn bits_at(bytes: &[u8], at: usize, width: u32) -> u64 {
    let byte = at >> 3;
    let word = bytes.get(byte..byte + 8).map_or(0, |b| u64::from_le_bytes(b.try_into().expect("eight bytes")));
    (word >> (at & 7)) & ((1u64 << width) - 1)
}

/// A curve's control-point codes packed at fixed widths ([`pack_codes`], [`Packing::Fixed`]),
/// read one point after another. The runtime's clips were made from a checked container, so
/// nothing is checked.
#[derive(Clone, Debug)]
pub(crate) struct FixedCodes<'a> {
    bytes: &'a [u8],
    /// The stream's first bit, and the next one to read.
    start: usize,
    at: usize,
    width: u32,
    /// The next point's index.
    next: u32,
    /// The current block's widths.
    widths: [u32; 3],
    two_back: [u32; 3],
    last: [u32; 3],
}

impl<'a> FixedCodes<'a> {
    /// The stream at byte `start` of `bytes`.
    pub(crate) fn new(bytes: &'a [u8], start: usize, width: u32) -> Self {
        Self { bytes, start: 8 * start, at: 8 * start, width, next: 0, widths: [0; 3], two_back: [0; 3], last: [0; 3] }
    }

    /// Back to the first point.
    pub(crate) fn restart(&mut self) {
        (self.at, self.next) = (self.start, 0);
    }

    /// The next point's codes.
    #[inline(always)]
    pub(crate) fn next(&mut self) -> [u32; 3] {
        let mut point = [0u32; 3];
        if self.next == 0 {
            for code in &mut point {
                *code = bits_at(self.bytes, self.at, self.width) as u32;
                self.at += self.width as usize;
            }
            self.last = point;
        } else {
            if (self.next - 1) % BLOCK as u32 == 0 {
                for w in &mut self.widths {
                    *w = bits_at(self.bytes, self.at, RICE_BITS) as u32;
                    self.at += RICE_BITS as usize;
                }
            }
            for (c, code) in point.iter_mut().enumerate() {
                let w = self.widths[c];
                let r = unzigzag(bits_at(self.bytes, self.at, w));
                self.at += w as usize;
                *code = predicted(&self.two_back, &self.last, c).wrapping_add(r) as u32;
            }
        }
        self.two_back = if self.next == 0 { point } else { self.last };
        self.last = point;
        self.next += 1;
        point
    }
}

/// A curve's knots as the runtime's [`Writer::knots`](super::Writer) packs them (deltas at
/// one width), read one after another.
#[derive(Clone, Debug)]
pub(crate) struct FixedKnots<'a> {
    bytes: &'a [u8],
    start: usize,
    at: usize,
    width: u32,
    least: u32,
    previous: u32,
}

impl<'a> FixedKnots<'a> {
    /// The stream at byte `start` of `bytes`, deltas of `width` bits less `least`.
    pub(crate) fn new(bytes: &'a [u8], start: usize, width: u32, least: u32) -> Self {
        Self { bytes, start: 8 * start, at: 8 * start, width, least, previous: 0 }
    }

    /// Back to the first knot.
    pub(crate) fn restart(&mut self) {
        (self.at, self.previous) = (self.start, 0);
    }

    /// The next knot's place.
    #[inline(always)]
    pub(crate) fn next(&mut self) -> u32 {
        let delta = bits_at(self.bytes, self.at, self.width) as u32;
        self.at += self.width as usize;
        self.previous = self.previous.wrapping_add(delta).wrapping_add(self.least);
        self.previous
    }
}

/// Values packed low bit first.
#[derive(Default)]
pub(crate) struct BitWriter {
    bytes: Vec<u8>,
    pending: u64,
    filled: u32,
}

impl BitWriter {
    /// `value`'s low `bits` (at most 32).
    pub(crate) fn push(&mut self, value: u64, bits: u32) {
        self.pending |= (value & ((1u64 << bits) - 1)) << self.filled;
        self.filled += bits;
        while self.filled >= 8 {
            self.bytes.push(self.pending as u8);
            self.pending >>= 8;
            self.filled -= 8;
        }
    }

    /// `z` as a Rice code of parameter `k` ([`rice_bits`]).
    pub(crate) fn rice(&mut self, z: u64, k: u32) {
        let mut quotient = z >> k;
        while quotient > 0 {
            let run = quotient.min(32) as u32;
            self.push((1 << run) - 1, run);
            quotient -= u64::from(run);
        }
        self.push(0, 1);
        self.push(z, k);
    }

    pub(crate) fn finish(mut self) -> Vec<u8> {
        if self.filled > 0 {
            self.bytes.push(self.pending as u8);
        }
        self.bytes
    }
}

/// Values unpacked low bit first, through a word of the next bits
/// kept in a register: a Rice code's length is known only once it is read, so each code waits
/// on the one before, and a load from memory at the bit position is no longer in that wait.
#[derive(Clone, Debug)]
pub(crate) struct BitReader<'a> {
    bytes: &'a [u8],
    /// The first byte not yet in `word`.
    next: usize,
    /// The next bits, low first: `filled` of them (at most 63) counted; above them zeros or
    /// the bits that follow, which a refill writes again as they are.
    word: u64,
    filled: u32,
}

impl<'a> BitReader<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, next: 0, word: 0, filled: 0 }
    }

    /// Tops `word` up to 56 bits or more, or to the end of the bytes: the eight bytes from
    /// `next` in one read while there are eight, and the whole bytes of them that fit counted.
    #[inline(always)]
    fn refill(&mut self) {
        if let Some(eight) = self.bytes.get(self.next..self.next + 8) {
            self.word |= u64::from_le_bytes(eight.try_into().expect("eight bytes")) << self.filled;
            let whole = (63 - self.filled) / 8;
            self.next += whole as usize;
            self.filled += 8 * whole;
        } else {
            while self.filled <= 55 && self.next < self.bytes.len() {
                self.word |= u64::from(self.bytes[self.next]) << self.filled;
                self.next += 1;
                self.filled += 8;
            }
        }
    }

    /// Drops `n` (at most `filled`) counted bits.
    #[inline(always)]
    fn skip(&mut self, n: u32) {
        self.word = self.word.checked_shr(n).unwrap_or(0);
        self.filled -= n;
    }

    /// The next `bits` (at most 32), or `None` past the end.
    pub(crate) fn take(&mut self, bits: u32) -> Option<u64> {
        debug_assert!(bits <= 32);
        if bits > self.filled {
            self.refill();
        }
        if bits > self.filled {
            return None;
        }
        let v = self.word & ((1u64 << bits) - 1);
        self.skip(bits);
        Some(v)
    }

    /// A Rice code of parameter `k` (at most 31): its quotient and its low bits, or `None`
    /// when the input ends first. The caller bounds the quotient before joining the two.
    #[inline(always)]
    pub(crate) fn rice(&mut self, k: u32) -> Option<(u64, u64)> {
        // Refilled only below 32 bits, so that most codes wait on no load from memory: each
        // code's length is known only once it is read, and a refill's address depends on it.
        if self.filled < 32 {
            self.refill();
        }
        // Most codes lie within the counted bits: read from the word.
        let run = self.word.trailing_ones();
        if run + 1 + k <= self.filled {
            let low = (self.word >> (run + 1)) & ((1u64 << k) - 1);
            self.skip(run + 1 + k);
            return Some((u64::from(run), low));
        }
        let quotient = self.ones()?;
        Some((quotient, self.take(k)?))
    }

    /// The bytes the bits taken so far began in (a field packed to a byte ends there).
    pub(crate) fn bytes_read(&self) -> usize {
        (8 * self.next - self.filled as usize).div_ceil(8)
    }

    /// How many one bits come before the next zero bit, both taken (a Rice code's quotient),
    /// or `None` when the input ends first.
    pub(crate) fn ones(&mut self) -> Option<u64> {
        let mut count = 0;
        loop {
            self.refill();
            if self.filled == 0 {
                return None;
            }
            // Bits above the counted ones are not yet known: the run stops at `filled`.
            let run = self.word.trailing_ones().min(self.filled);
            if run < self.filled {
                self.skip(run + 1);
                return Some(count + u64::from(run));
            }
            count += u64::from(run);
            self.skip(run);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values of every width 0..=32 read back as written, the last ones from the short word at
    /// the end of the bytes, and nothing past the end.
    #[test]
    fn bits_read_back_as_written_to_the_last_byte() {
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let values: Vec<(u64, u32)> = (0..500)
            .map(|i| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let bits = (i * 7 % 33) as u32;
                (state & ((1u64 << bits) - 1), bits)
            })
            .collect();
        let mut writer = BitWriter::default();
        values.iter().for_each(|&(v, bits)| writer.push(v, bits));
        let bytes = writer.finish();
        let mut reader = BitReader::new(&bytes);
        for (i, &(v, bits)) in values.iter().enumerate() {
            assert_eq!(reader.take(bits), Some(v), "value {i} of {bits} bits");
        }
        let left = 8 * bytes.len() - values.iter().map(|&(_, b)| b as usize).sum::<usize>();
        assert_eq!(reader.take(left as u32), Some(0), "the padding");
        assert_eq!(reader.take(1), None);
        // Unary runs across words: 0, 5, 40 and 70 ones, each ended by a zero; then the end.
        let mut writer = BitWriter::default();
        for run in [0u32, 5, 40, 70] {
            for _ in 0..run {
                writer.push(1, 1);
            }
            writer.push(0, 1);
        }
        writer.push(0b111, 3);
        let bytes = writer.finish();
        let mut reader = BitReader::new(&bytes);
        for run in [0, 5, 40, 70] {
            assert_eq!(reader.ones(), Some(run));
        }
        assert_eq!(reader.ones(), Some(3), "the padding's zeros end the last run");
        let all_ones = [0xffu8; 9];
        assert_eq!(BitReader::new(&all_ones).ones(), None, "no zero before the end");
        // Rice codes read as written, in the word and across its end, for every parameter.
        let values: Vec<(u64, u32)> =
            (0..400u64).map(|i| ((i * 2_654_435_761) % (1 << (i % 27)), (i % 32) as u32)).collect();
        let mut writer = BitWriter::default();
        values.iter().for_each(|&(z, k)| writer.rice(z, k));
        let bytes = writer.finish();
        let mut reader = BitReader::new(&bytes);
        for &(z, k) in &values {
            assert_eq!(reader.rice(k), Some((z >> k, z & ((1 << k) - 1))), "{z} at {k}");
        }
        // A code that fills the first word to its last bit (63 ones and the zero).
        let mut writer = BitWriter::default();
        writer.rice(63, 0);
        writer.push(0, 8);
        assert_eq!(BitReader::new(&writer.finish()).rice(0), Some((63, 0)));
    }

    #[test]
    fn codes_pack_as_residuals_and_unpack_to_the_same_codes_or_a_named_fault() {
        // A smooth ramp with a jump (a flip) in the middle, and the extremes of the width.
        let bits = 20;
        let top = (1u32 << bits) - 1;
        let mut codes: Vec<[u32; 3]> =
            (0..100u32).map(|i| [1000 + 37 * i, 500_000 - i * i, if i < 50 { 0 } else { top }]).collect();
        codes.push([top, 0, top]);
        let packed = pack_codes(&codes, bits, Packing::Rice);
        assert!(packed.len() * 8 < codes.len() * 3 * bits as usize / 2, "{} bytes: residuals are small", packed.len());
        assert_eq!(unpack_codes(&packed, codes.len(), bits).unwrap(), codes);
        assert_eq!(
            unpack_codes(&packed, codes.len(), 10).unwrap_err().to_string(),
            "control point 2 component 0 decodes to 1124, outside 10 bits"
        );
        // A run of one bits longer than any residual of the width: named, not shifted past 64.
        let mut runaway = BitWriter::default();
        runaway.push(0, 3 * 2);
        runaway.push(0, 3 * RICE_BITS);
        for _ in 0..40 {
            runaway.push(1, 1);
        }
        runaway.push(0, 8);
        assert_eq!(
            unpack_codes(&runaway.finish(), 2, 2).unwrap_err().to_string(),
            "control point 1 component 0: a residual's quotient 40 is larger than any of 2 bits"
        );
        assert_eq!(
            unpack_codes(&packed[..packed.len() - 2], codes.len(), bits).unwrap_err(),
            CodeFault::End(codes.len() - 1)
        );
    }

    #[test]
    fn the_runtime_packing_reads_back_the_codes_and_knots_the_rice_packing_holds_in_a_few_more_bytes() {
        // Blocks of every residual width (a ramp, a jump, the extremes, a still stretch), a
        // curve of one point, and a stream read again from its start.
        let bits = 20;
        let top = (1u32 << bits) - 1;
        let mut codes: Vec<[u32; 3]> =
            (0..100u32).map(|i| [1000 + 37 * i, 500_000 - i * i, if i < 50 { 0 } else { top }]).collect();
        codes.push([top, 0, top]);
        codes.extend(std::iter::repeat([7, 7, 7]).take(20));
        let (rice, fixed) = (pack_codes(&codes, bits, Packing::Rice), pack_codes(&codes, bits, Packing::Fixed));
        assert!(
            fixed.len() < rice.len() * 5 / 4,
            "{} bytes at fixed widths, {} as Rice codes",
            fixed.len(),
            rice.len()
        );
        let mut padded = vec![0xa5; 3];
        padded.extend(&fixed);
        padded.extend([0; 8]);
        let mut stream = FixedCodes::new(&padded, 3, bits);
        assert_eq!((0..codes.len()).map(|_| stream.next()).collect::<Vec<_>>(), codes);
        stream.restart();
        assert_eq!(stream.next(), codes[0]);
        let one = pack_codes(&[[5, 6, 7]], 3, Packing::Fixed);
        assert_eq!(FixedCodes::new(&[one, vec![0; 8]].concat(), 0, 3).next(), [5, 6, 7]);
        // Keys' knots (deltas less one) at one width: 2, 3, 9, 200.
        let mut out = super::super::Writer::default();
        out.knots(&[2, 3, 9, 200], 1, Packing::Fixed);
        // Count 4, width 8 (190 is the largest delta less one), byte length 4, the deltas.
        assert_eq!(out.bytes, [4, 8, 4, 1, 0, 5, 190]);
        let padded = [&out.bytes[..], &[0; 8]].concat();
        let mut knots = FixedKnots::new(&padded, 3, 8, 1);
        assert_eq!([knots.next(), knots.next(), knots.next(), knots.next()], [2, 3, 9, 200]);
        knots.restart();
        assert_eq!(knots.next(), 2);
    }

    #[test]
    fn knots_read_back_as_written_and_a_knot_off_its_places_is_named() {
        // Keys at 2, 3 and 9 of 10 (deltas less one: 1, 0, 5), read back, then no more.
        let keys = Places { unit: "key", last: 10, repeats: 1, least: 1 };
        let mut out = BitWriter::default();
        [1, 0, 5].iter().for_each(|&d| out.rice(d, 1));
        let packed = out.finish();
        let mut knots = Knots::new(&packed, 1, keys);
        assert_eq!([knots.next(), knots.next(), knots.next()], [Ok(2), Ok(3), Ok(9)]);
        assert_eq!(knots.bytes_read(), packed.len());
        // A delta past the last key, a cubic's sample taken a fourth time, a runaway run.
        let mut out = BitWriter::default();
        out.rice(11, 1);
        assert_eq!(Knots::new(&out.finish(), 1, keys).next().unwrap_err().to_string(), "key 12 is not inside 1..10");
        let samples = Places { unit: "sample", last: 20, repeats: 3, least: 0 };
        let mut out = BitWriter::default();
        [4, 0, 0, 0].iter().for_each(|&d| out.rice(d, 0));
        let packed = out.finish();
        let mut knots = Knots::new(&packed, 0, samples);
        assert_eq!([knots.next(), knots.next(), knots.next()], [Ok(4), Ok(4), Ok(4)]);
        assert_eq!(knots.next().unwrap_err().to_string(), "sample 4 repeated 4 times; at most 3");
        // 64 one bits: a quotient past the 57 knots the samples take.
        let runaway = [0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x00];
        assert_eq!(
            Knots::new(&runaway, 0, samples).next().unwrap_err().to_string(),
            "a delta's quotient 64 is past the timeline"
        );
        assert_eq!(Knots::new(&[0xff], 0, samples).next(), Err(KnotFault::End));
    }
}
