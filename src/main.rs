//! The `drape` command line: parse, run, map errors to exit codes (2: bad input, 1: failure).

mod cli;

fn main() {
    // Like any Unix filter, end quietly when the reader of our output goes away (`| head`),
    // instead of panicking on a broken pipe.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let code = match cli::run() {
        Ok(code) => code,
        Err(e) => {
            // drape's errors already name their cause; the alternate form would repeat it.
            eprintln!("drape: error: {e}");
            e.downcast_ref::<drape::Error>()
                .map_or(1, drape::Error::exit_code)
        }
    };
    std::process::exit(code);
}
