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
    // Mesa's Vulkan device-select layer connects to a Wayland display to learn the desktop's
    // default GPU; on a machine without one (a farm node, CI, ssh) libwayland then prints
    // "error: XDG_RUNTIME_DIR is invalid or not set in the environment." twice, which reads as
    // drape failing. drape picks its adapter itself, so without a display session the layer is
    // switched off (its own documented switch). Set before any thread starts.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none()
        && std::env::var_os("NODEVICE_SELECT").is_none()
    {
        std::env::set_var("NODEVICE_SELECT", "1");
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
