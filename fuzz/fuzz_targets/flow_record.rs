#![no_main]
//! Fuzzes relief-cli's `flow_record` parser (`relief_cli::fuzzing::flow_record`): untrusted bytes from a plan
//! folder or a spec file may be refused, never panic, and what is accepted passes its checks.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    relief_cli::fuzzing::flow_record(data);
});
