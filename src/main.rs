//! The `drape` command line: parse, run, map errors to exit codes (2: bad input, 1: failure).

mod cli;

fn main() {
    let code = match cli::run() {
        Ok(code) => code,
        Err(e) => {
            eprintln!("drape: error: {e:#}");
            e.downcast_ref::<drape::Error>()
                .map_or(1, drape::Error::exit_code)
        }
    };
    std::process::exit(code);
}
