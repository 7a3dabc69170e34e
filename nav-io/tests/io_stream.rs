//! Streaming readers and fast text: numbers parsed bit-identically to
//! `str::parse::<f64>`, nav lines formatted byte-identically to `Display`, the streaming and
//! whole-file readers agreeing, and no allocation per line (a counting allocator over a
//! generated input far larger than the memory the reader may use).

use nav_core::types::{ImuSample, NavSolution};
use nav_io::{
    parse_f64, read_imu_bin, read_imu_text, write_imu_bin, write_imu_text, write_nav_line,
    write_nav_line_display, ImuBinReader, ImuTextReader,
};
use proptest::prelude::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Read;
use std::path::Path;

/// Counts allocations and live bytes (peak kept) made by the current thread (the test
/// harness runs other tests on other threads at the same time).
struct Counting;

thread_local! {
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

// SAFETY: forwards to the system allocator; only counts (const thread-locals, no allocation).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let _ = ALLOCS.try_with(|a| a.set(a.get() + 1));
        let _ = LIVE.try_with(|v| {
            v.set(v.get() + l.size() as isize);
            let _ = PEAK.try_with(|p| p.set(p.get().max(v.get())));
        });
        // SAFETY: same layout contract as the caller's.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        let _ = LIVE.try_with(|v| v.set(v.get() - l.size() as isize));
        // SAFETY: p was allocated by System with l.
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// IMU text lines generated on the fly: `n` lines, never held in memory as a whole.
struct GeneratedImu {
    k: u64,
    n: u64,
    line: Vec<u8>,
    pos: usize,
}

impl GeneratedImu {
    fn new(n: u64) -> Self {
        Self {
            k: 0,
            n,
            line: Vec::with_capacity(256),
            pos: 0,
        }
    }
}

impl Read for GeneratedImu {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.pos == self.line.len() {
            if self.k == self.n {
                return Ok(0);
            }
            self.k += 1;
            let x = self.k as f64;
            self.line.clear();
            use std::io::Write;
            writeln!(
                self.line,
                "{} {:e} {:e} {:e} {:e} {:e} {:e}",
                200000.0 + 0.005 * x,
                1e-6 * (x * 0.1).sin(),
                -2.5e-7,
                3e-6 * (x * 0.01).cos(),
                0.01 * (x * 0.2).sin(),
                -1e-3,
                -0.049033 + 1e-9 * x
            )?;
            self.pos = 0;
        }
        let n = buf.len().min(self.line.len() - self.pos);
        buf[..n].copy_from_slice(&self.line[self.pos..self.pos + n]);
        self.pos += n;
        Ok(n)
    }
}

#[test]
fn streaming_a_large_generated_imu_record_allocates_nothing_per_line() {
    // 2,000,000 lines (~280 MB of text at ~140 bytes a line), generated as they are read.
    const N: u64 = 2_000_000;
    let mut rd =
        ImuTextReader::from_reader(Path::new("generated.txt"), GeneratedImu::new(N)).expect("open");
    // warm up: the line buffer reaches its size on the first lines
    for _ in 0..10 {
        rd.next().unwrap().unwrap();
    }
    let (a0, p0) = (ALLOCS.with(Cell::get), LIVE.with(Cell::get));
    PEAK.with(|p| p.set(p0));
    let mut count = 10u64;
    let mut last_t = 0.0;
    for r in &mut rd {
        let (s, line) = r.expect("valid line");
        assert_eq!(line as u64, count + 1);
        last_t = s.t_s;
        count += 1;
    }
    let allocs = ALLOCS.with(Cell::get) - a0;
    let peak_extra = PEAK.with(Cell::get) - p0;
    assert_eq!(count, N);
    assert_eq!(last_t, 200000.0 + 0.005 * N as f64);
    // Nothing allocated per line: the whole stream of 2e6 lines costs no allocation at all
    // beyond the first lines; memory stays what it was (the input is ~280 MB).
    assert_eq!(allocs, 0, "allocations while streaming {N} lines");
    assert!(
        peak_extra < 64 * 1024,
        "live heap grew by {peak_extra} bytes while streaming"
    );
}

#[test]
fn whole_file_readers_are_the_streaming_readers_collected() {
    let dir = tempfile::tempdir().unwrap();
    let samples: Vec<ImuSample> = (0..5000)
        .map(|k| {
            let x = k as f64;
            ImuSample {
                // a gap at k = 3000
                t_s: 1000.0 + 0.01 * x + if k >= 3000 { 0.5 } else { 0.0 },
                dtheta_rad: [1e-5 * x.sin(), -3e-9 * x, 7.7e-4 / (x + 1.0)],
                dv_mps: [0.049 * (x * 0.3).cos(), -1e-7, -0.0490332],
                temperature_c: f64::NAN,
            }
        })
        .collect();
    for (name, bin) in [
        ("imu.txt", false),
        ("imu.txt.gz", false),
        ("imu.bin", true),
        ("imu.bin.gz", true),
    ] {
        let p = dir.path().join(name);
        let rec = if bin {
            write_imu_bin(&p, &samples).unwrap();
            read_imu_bin(&p).unwrap()
        } else {
            write_imu_text(&p, &samples).unwrap();
            read_imu_text(&p).unwrap()
        };
        let streamed: Vec<(ImuSample, usize)> = if bin {
            ImuBinReader::open(&p)
                .unwrap()
                .map(Result::unwrap)
                .collect()
        } else {
            ImuTextReader::open(&p)
                .unwrap()
                .map(Result::unwrap)
                .collect()
        };
        assert_eq!(rec.samples.len(), samples.len(), "{name}");
        assert_eq!(streamed.len(), samples.len(), "{name}");
        for (k, ((a, line), b)) in streamed.iter().zip(&rec.samples).enumerate() {
            assert_eq!(a.t_s.to_bits(), b.t_s.to_bits(), "{name} sample {k}");
            assert_eq!(a.dv_mps, b.dv_mps);
            assert_eq!(a.dtheta_rad, b.dtheta_rad);
            assert_eq!(*line, k + 1);
            // written in shortest round-trip form: bit-exact
            assert_eq!(a.dtheta_rad, samples[k].dtheta_rad);
        }
        assert_eq!(rec.gaps.count(), 1, "{name}");
        assert_eq!(rec.gaps.gaps[0].line, 3001, "{name}");
    }
}

#[test]
fn binary_reader_errors_name_the_record_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.bin");
    let mut bytes = Vec::new();
    for (k, t) in [1.0f64, 2.0, 1.5].iter().enumerate() {
        bytes.extend_from_slice(&t.to_le_bytes());
        for i in 0..6 {
            let v = if k == 1 && i == 2 { f64::NAN } else { 0.0 };
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(&p, &bytes).unwrap();
    let e = read_imu_bin(&p).unwrap_err().to_string();
    assert!(e.contains("line 2") && e.contains("column 4"), "{e}");
    // truncated: a whole record and 10 bytes
    std::fs::write(&p, &bytes[..56 + 10]).unwrap();
    let e = read_imu_bin(&p).unwrap_err().to_string();
    assert!(e.contains("line 2") && e.contains("66 bytes"), "{e}");
    // non-monotonic time at record 3 (record 2 fixed)
    let mut ok = bytes.clone();
    ok[56 + 24..56 + 32].copy_from_slice(&0.0f64.to_le_bytes());
    std::fs::write(&p, &ok).unwrap();
    let e = read_imu_bin(&p).unwrap_err().to_string();
    assert!(e.contains("line 3"), "{e}");
}

fn nav(v: &[f64; 10], week: u16) -> NavSolution {
    NavSolution {
        week,
        t_s: v[0],
        lat_rad: v[1],
        lon_rad: v[2],
        h_m: v[3],
        vel_ned_mps: [v[4], v[5], v[6]],
        rpy_rad: [v[7], v[8], v[9]],
        ..NavSolution::default()
    }
}

fn fast_and_display(n: &NavSolution) -> (String, String) {
    let (mut a, mut b) = (Vec::new(), Vec::new());
    write_nav_line(&mut a, n).unwrap();
    write_nav_line_display(&mut b, n).unwrap();
    (String::from_utf8(a).unwrap(), String::from_utf8(b).unwrap())
}

#[test]
fn nav_lines_equal_display_on_ties_and_extremes() {
    // exact ties (ryu and Display differ there; the fast path must defer to Display),
    // extremes, zeros and non-finite values
    let hard = [
        -1514017065704403.2,
        200000.0 + 2f64.powi(-12),
        1514017065704403.2,
        0.5,
        -0.0,
        0.0,
        1e-320,
        f64::MAX,
        -f64::MIN_POSITIVE,
        9007199254740993.0,
        1e23,
        f64::NAN,
        f64::INFINITY,
        2.0f64.powi(-30) + 1.0,
        123456.0 + 2.0f64.powi(-20),
    ];
    for (i, &x) in hard.iter().enumerate() {
        let mut v = [1.0; 10];
        v[i % 10] = x;
        v[(i + 3) % 10] = x;
        let (a, b) = fast_and_display(&nav(&v, (i * 977) as u16));
        assert_eq!(a, b, "value {x:e}");
    }
}

/// Floats that end in exact binary fractions of a few bits (where ties live) or are random.
fn tie_prone() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<u64>().prop_map(f64::from_bits),
        (any::<i64>(), 0i32..40).prop_map(|(m, s)| (m >> 11) as f64 / 2f64.powi(s)),
        (0u32..1_000_000, 0i32..30).prop_map(|(m, s)| 200000.0 + m as f64 / 2f64.powi(s)),
        (-1e6f64..1e6),
        (-1.0f64..1.0).prop_map(|x| x * 1e-9),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 20_000, ..ProptestConfig::default() })]

    /// The fast nav line is `Display`'s, byte for byte.
    #[test]
    fn nav_line_is_byte_identical_to_display(
        v in proptest::array::uniform10(tie_prone()),
        week in any::<u16>(),
    ) {
        let (a, b) = fast_and_display(&nav(&v, week));
        prop_assert_eq!(a, b);
    }

    /// Every float written by `Display` or `{:e}` reads back to the same bits as with
    /// `str::parse` (fast-float2 is correctly rounded, as the standard library).
    #[test]
    fn parse_f64_is_bit_identical_to_std_on_printed_floats(x in tie_prone()) {
        for s in [format!("{x}"), format!("{x:e}"), format!("{x:.3}"), format!("{x:.17e}"), format!("{x:E}")] {
            let std: Option<f64> = s.parse().ok();
            let fast = parse_f64(&s);
            prop_assert_eq!(fast.map(f64::to_bits), std.map(f64::to_bits), "{}", s);
        }
    }

    /// Arbitrary decimal texts (many digits, signs, exponents, malformed forms): the same
    /// texts are accepted and give the same bits.
    #[test]
    fn parse_f64_accepts_what_std_accepts(
        s in "[+-]?[0-9]{0,25}(\\.[0-9]{0,25})?([eE][+-]?[0-9]{0,4})?[.eE+-]?",
    ) {
        let std: Option<f64> = s.parse().ok();
        prop_assert_eq!(parse_f64(&s).map(f64::to_bits), std.map(f64::to_bits), "{:?}", s);
    }
}

#[test]
fn parse_f64_special_spellings_match_std() {
    for s in [
        "nan",
        "NaN",
        "-nan",
        "+nan",
        "inf",
        "-inf",
        "+inf",
        "infinity",
        "Infinity",
        "-INF",
        "",
        ".",
        "-",
        "+",
        "e5",
        "1e",
        "1e+",
        "1.e3",
        ".5",
        "5.",
        "+.5e-3",
        "1_000",
        "0x10",
        " 1",
        "1 ",
        "1.5e400",
        "-1.5e-400",
        "00000.000001",
        "1e-320",
    ] {
        let std: Option<f64> = s.parse().ok();
        assert_eq!(
            parse_f64(s).map(f64::to_bits),
            std.map(f64::to_bits),
            "{s:?}"
        );
    }
}

fn tag_bytes(start_s: u32, frac: f64, pairs: &[(u32, u32)]) -> Vec<u8> {
    let mut b = vec![0u8; 60];
    b[..20].copy_from_slice(b"TIMETAG RTKLIB demo5");
    b.extend_from_slice(&123456u32.to_le_bytes());
    b.extend_from_slice(&start_s.to_le_bytes());
    b.extend_from_slice(&frac.to_le_bytes());
    for (t, p) in pairs {
        b.extend_from_slice(&t.to_le_bytes());
        b.extend_from_slice(&p.to_le_bytes());
    }
    b
}

#[test]
fn csv_streaming_rows_and_increments_equal_the_whole_file_readers() {
    use nav_io::{
        read_imu_csv, read_imu_csv_raw, Column, CsvTime, ImuCsvFormat, ImuCsvIncrements,
        ImuCsvReader, SampleConvention,
    };
    use std::fmt::Write as _;
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("log.csv.tag"),
        tag_bytes(1_752_003_261, 0.5, &[(15, 40), (1005, 900), (2002, 1800)]),
    )
    .unwrap();
    // a header with names, 201 rows of ticks (the sensor clock 0.1 % fast vs the tag)
    let mut s = String::from("ax,ay,az,gx,gy,gz,tick\n");
    for k in 0..=200 {
        let x = k as f64;
        writeln!(
            s,
            "{},{},{},{},{},{},{}",
            0.01 * (x * 0.1).sin(),
            -0.02,
            1.0 + 1e-3 * x,
            0.5 * (x * 0.05).cos(),
            -0.1,
            0.2,
            5000 + 10 * k
        )
        .unwrap();
    }
    let p = dir.path().join("log.csv");
    std::fs::write(&p, &s).unwrap();
    let mut fmt = ImuCsvFormat::rtklib_demo5_icm("log.csv.tag");
    fmt.skip_lines = 1;
    fmt.skip_last_rows = 1;
    fmt.columns.time = Some(Column::Name("tick".into()));
    for (conv, stretch) in [
        (SampleConvention::Trapezoid, true),
        (SampleConvention::IntervalMean, false),
    ] {
        fmt.convention = conv;
        fmt.time = CsvTime::TicksMs {
            tag_file: Some("log.csv.tag".into()),
            stretch_to_tag_end: stretch,
        };
        let raw = read_imu_csv_raw(&p, &fmt).unwrap();
        assert_eq!(raw.samples.len(), 201 - 1);
        assert_eq!(*raw.lines.last().unwrap(), 2 + 199);
        let rows: Vec<_> = ImuCsvReader::open(&p, &fmt)
            .unwrap()
            .map(Result::unwrap)
            .collect();
        assert_eq!(rows.len(), raw.samples.len());
        for ((r, line), (a, l)) in rows.iter().zip(raw.samples.iter().zip(&raw.lines)) {
            // Debug prints shortest round-trip digits: equal texts are equal bits (NaN too)
            assert_eq!(format!("{r:?}"), format!("{a:?}"));
            assert_eq!(line, l);
        }
        // the stretch places the last USED row at the tag's last tick only with the stretch
        let t_last = raw.samples.last().unwrap().t_s - raw.samples[0].t_s;
        if stretch {
            assert!((t_last - 2.002).abs() < 1e-9, "{t_last}");
        } else {
            assert!((t_last - 1.99).abs() < 1e-9, "{t_last}");
        }
        let inc = read_imu_csv(&p, &fmt).unwrap();
        let streamed: Vec<_> = ImuCsvIncrements::open(&p, &fmt)
            .unwrap()
            .map(Result::unwrap)
            .collect();
        assert_eq!(streamed.len(), inc.samples.len());
        assert_eq!(inc.samples.len(), 199);
        let lines = &inc.origin.as_ref().unwrap().lines;
        for ((a, line), (b, l)) in streamed.iter().zip(inc.samples.iter().zip(lines)) {
            assert_eq!(a.t_s.to_bits(), b.t_s.to_bits());
            assert_eq!(a.dtheta_rad, b.dtheta_rad);
            assert_eq!(a.dv_mps, b.dv_mps);
            assert_eq!(line, l);
        }
    }
    // an error in a row held back as one of the last rows is still an error, with its line
    let bad = s.replace(",7000\n", ",x\n");
    std::fs::write(&p, bad).unwrap();
    let e = ImuCsvReader::open(&p, &fmt)
        .and_then(|r| r.collect::<Result<Vec<_>, _>>())
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 202") && e.contains("column 7"), "{e}");
}
