//! The arguments of the `hw-bridge` sub-commands: clap structs of the binary only, each
//! converted into the library's typed options ([`cmd::RecordOptions`], [`cmd::ReplayOptions`],
//! [`cmd::SendOptions`], [`cmd::StreamOptions`]) by one `From` impl.

use clap::builder::{PossibleValuesParser, TypedValueParser};
use hw_bridge::cmd::{
    self, parse_seconds, parse_speed, parse_timeout, InputKind, DEFAULT_BAUD, DEFAULT_GNSS_BAUD,
    DEFAULT_LEAP_SECONDS, DEFAULT_LINGER_S, DEFAULT_MAX_GAP_S, DEFAULT_WRITE_TIMEOUT_S,
};
use std::path::PathBuf;
use std::str::FromStr;
use strum::VariantNames;

/// A clap value parser for a library option enum: its names are the possible values (listed
/// in `--help` and in the error for another value), each parsed with the enum's `FromStr`.
fn enum_parser<T>() -> impl TypedValueParser<Value = T>
where
    T: FromStr + VariantNames + Clone + Send + Sync + 'static,
    T::Err: std::error::Error + Send + Sync + 'static,
{
    PossibleValuesParser::new(T::VARIANTS.iter().copied()).try_map(|s| s.parse::<T>())
}

/// `record` arguments.
#[derive(clap::Args, Debug, Clone)]
pub struct RecordArgs {
    /// Serial port (device path; pseudo-terminals by path).
    #[arg(long)]
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = DEFAULT_BAUD)]
    pub baud: u32,
    /// Capture file to write. It is written as OUT.partial (locked: a second recorder of the
    /// same file refuses) and moved to OUT when the recording ends: at --duration,
    /// --idle-exit, --reopen-timeout, or Ctrl-C / SIGTERM, which end a recording normally
    /// (exit 0, the capture complete up to there). An existing OUT is refused unless --force;
    /// a link at OUT is replaced, never written through. A recording killed outright leaves
    /// what it received in OUT.partial.
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an existing capture (or link) at --out, and remove a leftover OUT.partial no
    /// recorder is writing (an interrupted recording's data).
    #[arg(long)]
    pub force: bool,
    /// Stop after this many seconds.
    #[arg(long, value_parser = parse_seconds)]
    pub duration: Option<f64>,
    /// Stop when no byte arrived for this many seconds after the first byte (before it, only
    /// `--duration` and `--first-byte-timeout` stop the recording).
    #[arg(long, value_parser = parse_timeout)]
    pub idle_exit: Option<f64>,
    /// Fail (exit 1) when no byte at all arrived within this many seconds of the start.
    #[arg(long, value_parser = parse_timeout)]
    pub first_byte_timeout: Option<f64>,
    /// When the port is lost, try to reopen it for at most this many seconds, then stop and
    /// report the capture incomplete (exit 2); without it, retry until another stop condition.
    #[arg(long, value_parser = parse_timeout)]
    pub reopen_timeout: Option<f64>,
    /// The recording starts before the sender: every stream begins at sequence number 0, so
    /// frames lost before a stream's first delivered frame are counted too (stored in the
    /// capture header, used by `replay`).
    #[arg(long)]
    pub streams_from_start: bool,
    /// Do not decode frames for the status line (e.g. when recording a GNSS receiver).
    #[arg(long)]
    pub raw: bool,
    /// Open the port without the exclusive lock, so another program (e.g. `hw-bridge send`
    /// on the same emulated board's pty) can use it at the same time.
    #[arg(long)]
    pub shared: bool,
    /// No live status line.
    #[arg(long)]
    pub quiet: bool,
}

impl From<&RecordArgs> for cmd::RecordOptions {
    fn from(a: &RecordArgs) -> Self {
        Self {
            port: a.port.clone(),
            baud: a.baud,
            out: a.out.clone(),
            duration_s: a.duration,
            idle_exit_s: a.idle_exit,
            first_byte_timeout_s: a.first_byte_timeout,
            reopen_timeout_s: a.reopen_timeout,
            streams_from_start: a.streams_from_start,
            raw: a.raw,
            shared: a.shared,
            quiet: a.quiet,
            force: a.force,
        }
    }
}

/// `replay` arguments.
#[derive(clap::Args, Debug, Clone)]
pub struct ReplayArgs {
    /// Capture file written by `record`.
    pub capture: PathBuf,
    /// Replay at this multiple of the recorded timing, in [0.001, 1e6] (default: 1 with
    /// `--to-port`, else as fast as possible).
    #[arg(long, conflicts_with = "as_fast_as_possible", value_parser = parse_speed)]
    pub speed: Option<f64>,
    /// Longest pause between two records when pacing, in recorded seconds: a larger jump of
    /// the recorded time (a link down for minutes, a damaged timestamp) is paced as this long
    /// and counted. Timestamps going backwards are counted and not waited for.
    #[arg(long, default_value_t = DEFAULT_MAX_GAP_S, value_parser = parse_timeout)]
    pub max_gap: f64,
    /// Ignore the recorded timing.
    #[arg(long)]
    pub as_fast_as_possible: bool,
    /// Also write the recorded bytes, in the recorded chunks, to this port.
    #[arg(long)]
    pub to_port: Option<String>,
    /// Baud rate of `--to-port`.
    #[arg(long, default_value_t = DEFAULT_BAUD)]
    pub baud: u32,
    /// Directory for imu.txt, gnss.txt, nav.txt, health.txt and replay-summary.txt.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// What the capture contains.
    #[arg(long, value_parser = enum_parser::<InputKind>(), default_value_t = InputKind::Frames)]
    pub input: InputKind,
    /// GPS - UTC leap seconds for NMEA input, in the leap-second table's range [0, 18].
    #[arg(long, default_value_t = DEFAULT_LEAP_SECONDS, allow_hyphen_values = true)]
    pub leap_seconds: i64,
    /// Print every rejected chunk with its byte offset.
    #[arg(long)]
    pub verbose: bool,
    /// Run the host filter on the decoded IMU and GNSS frames as `host-sim run --config`
    /// does on files (same model, noise, initialisation, outages), writing its `nav.txt`,
    /// `std.txt`, `bias.txt`, `innovations.txt` and `metrics.json` into `--out`. The
    /// configuration's own data files (or `--case`'s) are read for the truth, week and
    /// outages; the IMU samples and GNSS fixes come from the capture.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A case directory written by `host-sim simulate` (truth, outages, GPS week), as in
    /// `host-sim run --case`.
    #[arg(long, requires = "config")]
    pub case: Option<PathBuf>,
    /// Error-state model for `--config` (default: the configuration's).
    #[arg(long, requires = "config", value_parser = enum_parser::<nav_engine::run::Model>())]
    pub model: Option<nav_engine::run::Model>,
    /// f32 covariance (as on the MCU) for `--config`.
    #[arg(long, requires = "config")]
    pub f32: bool,
}

impl From<&ReplayArgs> for cmd::ReplayOptions {
    /// The command line keeps only the frames its outputs need.
    fn from(a: &ReplayArgs) -> Self {
        Self {
            capture: a.capture.clone(),
            speed: a.speed,
            max_gap_s: a.max_gap,
            as_fast_as_possible: a.as_fast_as_possible,
            to_port: a.to_port.clone(),
            baud: a.baud,
            out: a.out.clone(),
            input: a.input,
            leap_seconds: a.leap_seconds,
            verbose: a.verbose,
            filter: a.config.as_ref().map(|c| {
                let mut spec = nav_engine::RunSpec::new(c);
                spec.case = a.case.clone();
                spec.set.model = a.model;
                spec.set.precision = a.f32.then_some(nav_engine::run::Precision::F32);
                spec
            }),
            keep_frames: false,
        }
    }
}

/// `send` arguments.
#[derive(clap::Args, Debug, Clone)]
pub struct SendArgs {
    /// Case directory with imu.txt and optionally gnss.txt (as `host-sim simulate` writes).
    #[arg(long)]
    pub case: PathBuf,
    /// Serial port to send to.
    #[arg(long)]
    pub port: String,
    /// Baud rate.
    #[arg(long, default_value_t = DEFAULT_BAUD)]
    pub baud: u32,
    /// Speed-up over real time (sample times), in [0.001, 1e6].
    #[arg(long, default_value_t = 1.0, conflicts_with = "as_fast_as_possible", value_parser = parse_speed)]
    pub rate_x: f64,
    /// Send as fast as the port takes it.
    #[arg(long)]
    pub as_fast_as_possible: bool,
    /// Keep the port open this long after the last byte so the receiver drains it, s.
    #[arg(long, default_value_t = DEFAULT_LINGER_S, value_parser = parse_seconds)]
    pub linger_s: f64,
    /// Fail (exit 1) when the port takes no byte for this many seconds (nothing reads it),
    /// also while waiting at the end for the bytes written to drain.
    #[arg(long, default_value_t = DEFAULT_WRITE_TIMEOUT_S, value_parser = parse_timeout)]
    pub write_timeout: f64,
    /// No live status line.
    #[arg(long)]
    pub quiet: bool,
    /// Also write every byte sent, exactly as written to the port, to this file (e.g. to run
    /// the same bytes through a host model of the receiver); a file or link under the name is
    /// replaced (a link never written through), one of the case's own files is refused.
    #[arg(long)]
    pub copy_to: Option<PathBuf>,
    /// Open the port without the exclusive lock, so another program (e.g. `hw-bridge record`
    /// on the same emulated board's pty) can use it at the same time.
    #[arg(long)]
    pub shared: bool,
}

impl From<&SendArgs> for cmd::SendOptions {
    fn from(a: &SendArgs) -> Self {
        Self {
            case: a.case.clone(),
            port: a.port.clone(),
            baud: a.baud,
            rate_x: a.rate_x,
            as_fast_as_possible: a.as_fast_as_possible,
            linger_s: a.linger_s,
            write_timeout_s: a.write_timeout,
            quiet: a.quiet,
            copy_to: a.copy_to.clone(),
            shared: a.shared,
        }
    }
}

/// `stream` arguments.
#[derive(clap::Args, Debug, Clone)]
pub struct StreamArgs {
    /// Port of the navigation board (wire-protocol frames).
    #[arg(long)]
    pub port: String,
    /// Baud rate of `--port`.
    #[arg(long, default_value_t = DEFAULT_BAUD)]
    pub baud: u32,
    /// Port of a separate GNSS receiver (NMEA and/or UBX).
    #[arg(long)]
    pub gnss_port: Option<String>,
    /// Baud rate of `--gnss-port`.
    #[arg(long, default_value_t = DEFAULT_GNSS_BAUD)]
    pub gnss_baud: u32,
    /// GPS - UTC leap seconds for NMEA input.
    #[arg(long, default_value_t = DEFAULT_LEAP_SECONDS)]
    pub leap_seconds: i64,
    /// Stop after this many seconds.
    #[arg(long, value_parser = parse_seconds)]
    pub duration: Option<f64>,
    /// Run the filter on the host too: the firmware's own application (18-state NBK, f32
    /// covariance, started at the first fix) on the IMU frames of `--port` and the GNSS fixes
    /// of both ports; its solution is shown next to the board's.
    #[arg(long)]
    pub host_filter: bool,
}

impl From<&StreamArgs> for cmd::StreamOptions {
    fn from(a: &StreamArgs) -> Self {
        Self {
            port: a.port.clone(),
            baud: a.baud,
            gnss_port: a.gnss_port.clone(),
            gnss_baud: a.gnss_baud,
            leap_seconds: a.leap_seconds,
            duration_s: a.duration,
            host_filter: a.host_filter,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    enum Cmd {
        Record(RecordArgs),
        Replay(ReplayArgs),
        Send(SendArgs),
        Stream(StreamArgs),
    }

    fn parse(args: &[&str]) -> Cmd {
        Cmd::try_parse_from(std::iter::once("hw-bridge").chain(args.iter().copied())).unwrap()
    }

    /// The command line's defaults are the typed options' (but for what the command line
    /// says differently: a status line, no frames kept, pacing chosen by `--to-port`).
    #[test]
    fn the_arguments_convert_into_the_typed_options_with_the_same_defaults() {
        let Cmd::Record(a) = parse(&["record", "--port", "p", "--out", "c.cap"]) else {
            panic!()
        };
        let want = cmd::RecordOptions {
            quiet: false,
            ..cmd::RecordOptions::new("p", "c.cap")
        };
        assert_eq!(cmd::RecordOptions::from(&a), want);
        let Cmd::Record(a) = parse(&[
            "record",
            "--port",
            "p",
            "--out",
            "c.cap",
            "--duration",
            "2",
            "--idle-exit",
            "0.5",
        ]) else {
            panic!()
        };
        let o = cmd::RecordOptions::from(&a);
        assert_eq!((o.duration_s, o.idle_exit_s), (Some(2.0), Some(0.5)));

        let Cmd::Replay(a) = parse(&["replay", "c.cap"]) else {
            panic!()
        };
        let want = cmd::ReplayOptions {
            as_fast_as_possible: false,
            keep_frames: false,
            ..cmd::ReplayOptions::new("c.cap")
        };
        assert_eq!(cmd::ReplayOptions::from(&a), want);
        let Cmd::Replay(a) = parse(&[
            "replay",
            "c.cap",
            "--input",
            "gnss",
            "--max-gap",
            "2",
            "--config",
            "r.toml",
            "--model",
            "nbk",
            "--f32",
        ]) else {
            panic!()
        };
        let o = cmd::ReplayOptions::from(&a);
        assert_eq!(o.input, InputKind::Gnss);
        assert_eq!(o.max_gap_s, 2.0);
        let spec = o.filter.expect("--config runs the filter");
        assert_eq!(spec.config, PathBuf::from("r.toml"));
        assert_eq!(spec.set.model, Some(nav_engine::run::Model::Nbk));
        assert_eq!(spec.set.precision, Some(nav_engine::run::Precision::F32));

        let Cmd::Send(a) = parse(&["send", "--case", "d", "--port", "p"]) else {
            panic!()
        };
        let want = cmd::SendOptions {
            quiet: false,
            ..cmd::SendOptions::new("d", "p")
        };
        assert_eq!(cmd::SendOptions::from(&a), want);
        let Cmd::Send(a) = parse(&["send", "--case", "d", "--port", "p", "--write-timeout", "3"])
        else {
            panic!()
        };
        assert_eq!(cmd::SendOptions::from(&a).write_timeout_s, 3.0);

        let Cmd::Stream(a) = parse(&["stream", "--port", "p", "--duration", "4"]) else {
            panic!()
        };
        let want = cmd::StreamOptions {
            duration_s: Some(4.0),
            ..cmd::StreamOptions::new("p")
        };
        assert_eq!(cmd::StreamOptions::from(&a), want);
    }

    #[test]
    fn a_wrong_input_kind_or_model_lists_the_valid_names() {
        for (args, want) in [
            (vec!["replay", "c.cap", "--input", "nmea"], "frames, gnss"),
            (
                vec!["replay", "c.cap", "--config", "r.toml", "--model", "kf"],
                "kf-gins, kf-gins-feedback",
            ),
        ] {
            let e = Cmd::try_parse_from(std::iter::once("hw-bridge").chain(args.iter().copied()))
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default();
            assert!(e.contains(want), "{args:?}: {e}");
        }
    }
}
