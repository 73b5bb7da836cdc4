//! `Container::parse` on arbitrary bytes. A stream it accepts at this crate's minor version is
//! canonical, so writing its sections back must give the same bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pwgs_bitstream::{Container, MINOR_VERSION, write_container};

fuzz_target!(|data: &[u8]| {
    let Ok(container) = Container::parse(data) else { return };
    if container.minor == MINOR_VERSION {
        let sections: Vec<_> = container.sections.iter().map(|s| (s.tag, s.payload.to_vec())).collect();
        assert_eq!(write_container(&sections), data, "a parsed stream does not re-serialize to itself");
    }
});
