//! FK request decoding (REST single and batch bodies, WebSocket message) and
//! evaluation against built-in robots: client errors or finite rigid poses.
//! The checks are `kinserve_testkit::fuzzing::check_fk_request`.

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    kinserve_testkit::fuzzing::check_fk_request(data);
});
