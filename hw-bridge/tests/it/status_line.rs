//! The live status line of `stream` written into a file or a pipe: plain lines, no terminal
//! control codes (those rewrite the line in place on a terminal only).
#![cfg(unix)]

use super::link::pair;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_hw-bridge");

#[test]
fn stream_status_into_a_pipe_has_no_escape_codes() {
    let (_master, _slave, name) = pair();
    let o = Command::new(BIN)
        .args(["stream", "--duration", "0.8", "--port"])
        .arg(&name)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    // the status was written (at least once in 0.8 s at 4 per second), line by line
    let lines: Vec<&str> = err.lines().filter(|l| l.contains("frames/s")).collect();
    assert!(!lines.is_empty(), "{err:?}");
    assert!(!err.contains('\x1b') && !err.contains('\r'), "{err:?}");
    assert!(
        lines
            .iter()
            .all(|l| l.trim_start().starts_with("0.0 frames/s")),
        "{err:?}"
    );
}

/// A message beside the status line (a port lost) is a line of its own; into a file or a pipe
/// no blank line before it (on a terminal the shown status line is ended first).
#[test]
fn a_message_into_a_pipe_is_a_plain_line() {
    use hw_bridge::status::StatusLine;
    use std::io::IsTerminal;
    use std::time::Duration;
    let hidden = StatusLine::new(Duration::from_millis(500), false);
    assert_eq!(hidden.message_line("port lost"), "port lost\n");
    let shown = StatusLine::new(Duration::from_millis(500), true);
    let want = if std::io::stderr().is_terminal() {
        "\nport lost\n"
    } else {
        "port lost\n"
    };
    assert_eq!(shown.message_line("port lost"), want);
}
