//! IK request decoding (REST single and batch bodies, WebSocket `ik`
//! message), validation and solving against built-in robots: client errors,
//! or answers within the limits whose pose and errors are honest.
//! The checks are `kinserve_testkit::fuzzing::check_ik_request`.

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    kinserve_testkit::fuzzing::check_ik_request(data);
});
