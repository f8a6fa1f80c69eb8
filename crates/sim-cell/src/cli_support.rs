//! What the workspace's two binaries (`sim-cell` and `handclasp`) share at the process edge. Built
//! only with the `cli` feature.

/// Ends the process quietly with exit 0 when printing fails because stdout was closed early
/// (`handclasp … | head`, `sim-cell … | head`): the reader has what it wanted, so no broken-pipe
/// panic (exit 101). Every other panic goes to the default hook. (`print!` panics on a failed write; SIGPIPE stays ignored,
/// as Rust sets it, so the write error is what is seen here.)
pub fn exit_quietly_on_broken_pipe() {
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to stdout")
            && message.to_ascii_lowercase().contains("broken pipe")
        {
            std::process::exit(0);
        }
        default_hook(info);
    }));
}
