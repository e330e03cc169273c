//! Address mapping: a physical byte address -> (channel, bank group, bank, row,
//! column). Fields are bit slices above the line offset, ordered by the config's
//! `mapping` string from most to least significant.

use super::MemError;
use super::config::GeometryCfg;

/// Where a line lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Loc {
    pub channel: u32,
    pub bank_group: u32,
    /// Bank within its group.
    pub bank: u32,
    pub row: u32,
    /// Line index within the row.
    pub column: u32,
}

impl Loc {
    /// Flat bank index within the channel (bank group major).
    pub fn flat_bank(&self, banks_per_group: u32) -> u32 {
        self.bank_group * banks_per_group + self.bank
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Field {
    Row,
    Bank,
    BankGroup,
    Channel,
    Column,
}

#[derive(Clone, Debug, PartialEq)]
pub struct AddrMap {
    /// (field, shift, mask) from the least significant field up.
    slices: Vec<(Field, u32, u64)>,
    line_shift: u32,
    capacity: u64,
    /// No `bankgroup` field: `bank` is the flat bank index, bank group in its low
    /// bits (consecutive banks alternate groups, like GPGPU-Sim's indexing).
    flat_bank: bool,
    bg_bits: u32,
}

impl AddrMap {
    pub fn new(g: &GeometryCfg, mapping: &str) -> Result<AddrMap, MemError> {
        let names = ["row", "bank", "bankgroup", "channel", "column"];
        if mapping.trim().is_empty() {
            return Err(MemError::Config(
                "mem.mapping is empty; e.g. row:bank:channel:column:bankgroup".into(),
            ));
        }
        let mut seen = Vec::new();
        for tok in mapping.split(':') {
            let f = match tok.trim() {
                "row" => Field::Row,
                "bank" => Field::Bank,
                "bankgroup" => Field::BankGroup,
                "channel" => Field::Channel,
                "column" => Field::Column,
                other => {
                    return Err(MemError::Config(format!(
                        "mem.mapping = '{mapping}': unknown field '{other}'; use each of {} once, separated by ':'",
                        names.join(", ")
                    )));
                }
            };
            if seen.contains(&f) {
                return Err(MemError::Config(format!(
                    "mem.mapping = '{mapping}': field '{}' appears twice; use each field once",
                    tok.trim()
                )));
            }
            seen.push(f);
        }
        let flat_bank = !seen.contains(&Field::BankGroup);
        let required = [Field::Row, Field::Bank, Field::Channel, Field::Column];
        if required.iter().any(|f| !seen.contains(f)) {
            return Err(MemError::Config(format!(
                "mem.mapping = '{mapping}': needs row, bank, channel and column (bankgroup is optional), e.g. row:bank:channel:column:bankgroup"
            )));
        }
        let bits = |f: Field| -> u32 {
            let n = match f {
                Field::Row => g.rows as u64,
                Field::Bank if flat_bank => g.banks() as u64,
                Field::Bank => g.banks_per_group as u64,
                Field::BankGroup => g.bank_groups as u64,
                Field::Channel => g.channels as u64,
                Field::Column => g.lines_per_row(),
            };
            n.trailing_zeros()
        };
        let line_shift = g.line_bytes.trailing_zeros();
        let mut shift = line_shift;
        let mut slices = Vec::new();
        for &f in seen.iter().rev() {
            let b = bits(f);
            slices.push((f, shift, (1u64 << b) - 1));
            shift += b;
        }
        Ok(AddrMap {
            slices,
            line_shift,
            capacity: g.capacity(),
            flat_bank,
            bg_bits: g.bank_groups.trailing_zeros(),
        })
    }

    pub fn capacity(&self) -> u64 {
        self.capacity
    }

    /// Decodes an address; errors name the address and the capacity.
    pub fn decode(&self, addr: u64) -> Result<Loc, MemError> {
        if addr >= self.capacity {
            return Err(MemError::Address(format!(
                "address {addr:#x} is beyond the configured capacity of {} bytes ({:#x}); use a smaller address or a larger mem.geometry",
                self.capacity, self.capacity
            )));
        }
        Ok(self.decode_unchecked(addr))
    }

    #[inline]
    pub fn decode_unchecked(&self, addr: u64) -> Loc {
        let mut l = Loc {
            channel: 0,
            bank_group: 0,
            bank: 0,
            row: 0,
            column: 0,
        };
        for &(f, s, m) in &self.slices {
            let v = ((addr >> s) & m) as u32;
            match f {
                Field::Row => l.row = v,
                Field::Bank => l.bank = v,
                Field::BankGroup => l.bank_group = v,
                Field::Channel => l.channel = v,
                Field::Column => l.column = v,
            }
        }
        if self.flat_bank {
            l.bank_group = l.bank & ((1 << self.bg_bits) - 1);
            l.bank >>= self.bg_bits;
        }
        l
    }

    /// The address of the first byte of a location (inverse of `decode`).
    pub fn encode(&self, l: &Loc) -> u64 {
        let mut a = 0u64;
        for &(f, s, m) in &self.slices {
            let v = match f {
                Field::Row => l.row,
                Field::Bank if self.flat_bank => (l.bank << self.bg_bits) | l.bank_group,
                Field::Bank => l.bank,
                Field::BankGroup => l.bank_group,
                Field::Channel => l.channel,
                Field::Column => l.column,
            } as u64;
            a |= (v & m) << s;
        }
        a
    }

    /// The line index of an address (address / line size).
    pub fn line(&self, addr: u64) -> u64 {
        addr >> self.line_shift
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_mapping_rotates_bank_groups_then_columns_then_channels() {
        let g = GeometryCfg::default();
        let m = AddrMap::new(&g, "row:bank:channel:column:bankgroup").unwrap();
        let l0 = m.decode(0).unwrap();
        let l1 = m.decode(64).unwrap();
        assert_eq!((l0.bank_group, l1.bank_group), (0, 1));
        assert_eq!(m.decode(4 * 64).unwrap().column, 1);
        // 32 KB per channel: 4 bank groups x one 8 KB row.
        assert_eq!(m.decode(32 * 1024 - 64).unwrap().channel, 0);
        assert_eq!(m.decode(32 * 1024).unwrap().channel, 1);
        for a in [0u64, 64, 12345 * 64, g.capacity() - 64] {
            assert_eq!(m.encode(&m.decode(a).unwrap()), a);
        }
        let e = m.decode(g.capacity()).unwrap_err();
        assert!(matches!(e, MemError::Address(_)), "{e:?}");
        assert!(e.to_string().contains("beyond"));
    }

    #[test]
    fn simtrax_mapping_keeps_an_8kb_row_contiguous() {
        let g = GeometryCfg::default();
        let m = AddrMap::new(&g, "row:bank:channel:column").unwrap();
        let a = m.decode(0).unwrap();
        let b = m.decode(8192 - 64).unwrap();
        assert_eq!((a.channel, a.bank, a.row), (b.channel, b.bank, b.row));
        assert_eq!(m.decode(8192).unwrap().channel, 1);
        // The next row of channel 0 is in the next bank, of another bank group.
        let n = m.decode(16 * 8192).unwrap();
        assert_eq!((n.channel, n.bank_group, n.bank), (0, 1, 0));
        for a in [0u64, 64, 16 * 8192, 999 * 64] {
            assert_eq!(m.encode(&m.decode(a).unwrap()), a);
        }
    }

    #[test]
    fn bad_mappings_are_named() {
        let g = GeometryCfg::default();
        assert!(
            AddrMap::new(&g, "row:bank:channel")
                .unwrap_err()
                .to_string()
                .contains("needs row")
        );
        assert!(
            AddrMap::new(&g, "row:row:bank:channel:column")
                .unwrap_err()
                .to_string()
                .contains("twice")
        );
        assert!(
            AddrMap::new(&g, "row:bnk:channel:column:bankgroup")
                .unwrap_err()
                .to_string()
                .contains("'bnk'")
        );
    }
}
