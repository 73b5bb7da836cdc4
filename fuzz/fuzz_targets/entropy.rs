//! The entropy decoder: `FrequencyTable::read` and a `SymbolDecoder` reading values and
//! adaptive bits from arbitrary coded data. Symbols that decode must encode back to data that
//! decodes to the same symbols.
//!
//! Input: `tables - 1` (u8, taken mod 4), a script (u8 length, then one byte per step: high bit
//! set = a bit in context `byte & 3`, else a value from table `byte % tables`; repeated; empty =
//! values channel by channel, as attribute blocks are coded), the symbol count (varint, at most
//! 2^16), the tables, then the coded data. An attribute section minus its steps, behind the
//! first four fields, is a valid input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pwgs_bitstream::FieldReader;
use pwgs_codec::stream::entropy::{BitContext, EntropyError, FrequencyTable, SymbolDecoder, SymbolEncoder};

const MAX_SYMBOLS: u32 = 1 << 16;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Symbol {
    Value { table: usize, value: i32 },
    Bit { context: usize, bit: bool },
}

/// What the script byte of step `i` asks for: `Err(context)` for a bit, `Ok(table)` for a value.
fn step(script: &[u8], tables: usize, i: usize) -> Result<usize, usize> {
    match script.get(i % script.len().max(1)) {
        None => Ok(i % tables),
        Some(&b) if b & 0x80 != 0 => Err(usize::from(b & 3)),
        Some(&b) => Ok(usize::from(b) % tables),
    }
}

fn decode(tables: &[FrequencyTable], script: &[u8], count: usize, coded: &[u8]) -> Result<Vec<Symbol>, EntropyError> {
    let mut decoder = SymbolDecoder::new(coded)?;
    let mut contexts = [BitContext::default(); 4];
    let mut symbols = Vec::with_capacity(count);
    for i in 0..count {
        symbols.push(match step(script, tables.len(), i) {
            Ok(table) => Symbol::Value { table, value: decoder.value(&tables[table])? },
            Err(context) => Symbol::Bit { context, bit: decoder.bit(&mut contexts[context])? },
        });
    }
    decoder.finish()?;
    Ok(symbols)
}

fn encode(tables: &[FrequencyTable], symbols: &[Symbol]) -> Vec<u8> {
    let mut encoder = SymbolEncoder::new();
    let mut contexts = [BitContext::default(); 4];
    for symbol in symbols {
        match *symbol {
            Symbol::Value { table, value } => encoder.value(&tables[table], value),
            Symbol::Bit { context, bit } => encoder.bit(&mut contexts[context], bit),
        }
    }
    encoder.finish()
}

fuzz_target!(|data: &[u8]| {
    let mut r = FieldReader::new("fuzz input", data);
    let Ok(table_count) = r.u8("tables").map(|n| usize::from(n % 4) + 1) else { return };
    let Ok(script) = r.u8("script length").and_then(|n| r.bytes("script", usize::from(n))) else { return };
    let Ok(count) = r.varint("symbol count") else { return };
    let count = count.min(MAX_SYMBOLS) as usize;
    let Ok(tables) = (0..table_count).map(|_| FrequencyTable::read(&mut r)).collect::<Result<Vec<_>, _>>() else {
        return;
    };
    let Ok(symbols) = decode(&tables, script, count, r.rest()) else { return };
    let recoded = encode(&tables, &symbols);
    assert_eq!(decode(&tables, script, count, &recoded), Ok(symbols), "decoded symbols do not survive re-encoding");
});
