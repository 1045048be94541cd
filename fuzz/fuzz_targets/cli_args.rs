//! The CLI's argument-to-settings path: a command line (a subcommand chosen by the first byte,
//! then arguments separated by NUL or space bytes) parsed by clap and mapped onto the checked
//! library settings of its job, without reading a file or starting work
//! (`relief_cli::app::settings_from_args`). It may refuse the arguments; it must not panic,
//! and a value it accepts must survive the JSON round trip of a `relief run` spec and pass
//! its check again (an error naming `MAPPING_BUG` is a bug).
#![no_main]

use libfuzzer_sys::fuzz_target;

const COMMANDS: [&str; 13] = [
    "amplify",
    "synthesize",
    "compress",
    "fit-procedural",
    "refine",
    "analyze",
    "quilt",
    "validate",
    "volume",
    "decompress",
    "flow",
    "masks",
    "erode",
];

fuzz_target!(|data: &[u8]| {
    let Some((&first, rest)) = data.split_first() else {
        return;
    };
    let mut args = vec![
        "relief".to_string(),
        COMMANDS[first as usize % COMMANDS.len()].to_string(),
    ];
    args.extend(
        rest.split(|&b| b == 0 || b == b' ')
            .filter(|t| !t.is_empty())
            .map(|t| String::from_utf8_lossy(t).into_owned()),
    );
    if let Err(e) = relief_cli::app::settings_from_args(&args) {
        let msg = format!("{e:#}");
        assert!(
            !msg.contains(relief_cli::app::MAPPING_BUG),
            "{args:?}: {msg}"
        );
    }
});
