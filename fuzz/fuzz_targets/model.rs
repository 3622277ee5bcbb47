//! Robot model parsing and validation, then FK of the validated model at
//! in-limit configurations: no panic, no hang, finite rigid poses.
//! The checks are `kinserve_testkit::fuzzing::check_model`.

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    kinserve_testkit::fuzzing::check_model(data);
});
