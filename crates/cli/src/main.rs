//! `relief`: inspect, convert, preview and make terrain rasters (DEMs). The whole command
//! line lives in [`relief_cli::app`].

fn main() -> std::process::ExitCode {
    relief_cli::app::main()
}
