//! Capture files: round trip, link-reset events, truncated and corrupt files.

use hw_bridge::capture::{
    CaptureError, CaptureHeader, CaptureReader, CaptureWriter, Record, LINK_RESET, MAGIC,
};

fn header() -> CaptureHeader {
    CaptureHeader {
        port: "/dev/ttyUSB0".into(),
        baud: 921_600,
        start_unix_ns: 1_763_700_000_123_456_789,
        tool: "hw-bridge test".into(),
        streams_from_start: false,
    }
}

fn records() -> Vec<Record> {
    vec![
        Record::Data {
            t_ns: 0,
            bytes: vec![0, 1, 2, 3],
        },
        Record::Data {
            t_ns: 5_000_000,
            bytes: (0..=255).collect(),
        },
        Record::LinkReset { t_ns: 7_000_000 },
        Record::Data {
            t_ns: 9_000_001,
            bytes: vec![0xFF; 3],
        },
    ]
}

fn write_all() -> Vec<u8> {
    let mut w = CaptureWriter::new(Vec::new(), &header()).unwrap();
    for r in records() {
        w.write(&r).unwrap();
    }
    w.into_inner()
}

#[test]
fn capture_round_trips_header_records_and_link_resets() {
    let bytes = write_all();
    let rd = CaptureReader::new(&bytes[..]).unwrap();
    assert_eq!(rd.header(), &header());
    let got: Vec<Record> = rd.map(|r| r.unwrap()).collect();
    assert_eq!(got, records());
}

#[test]
fn capture_layout_is_the_documented_one() {
    let bytes = write_all();
    assert_eq!(&bytes[..8], MAGIC);
    let hlen = u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize;
    let text = std::str::from_utf8(&bytes[12..12 + hlen]).unwrap();
    assert!(text.contains("baud=921600\n"), "{text}");
    let r0 = &bytes[12 + hlen..];
    assert_eq!(u64::from_le_bytes(r0[..8].try_into().unwrap()), 0);
    assert_eq!(u32::from_le_bytes(r0[8..12].try_into().unwrap()), 4);
    assert_eq!(&r0[12..16], &[0, 1, 2, 3]);
    // The link-reset record: 12 bytes with bit 31 set.
    let r2 = &r0[16 + 12 + 256..];
    assert_eq!(u64::from_le_bytes(r2[..8].try_into().unwrap()), 7_000_000);
    assert_eq!(
        u32::from_le_bytes(r2[8..12].try_into().unwrap()),
        LINK_RESET
    );
}

#[test]
fn truncated_capture_returns_every_complete_record_then_says_where() {
    let bytes = write_all();
    let cut = &bytes[..bytes.len() - 2];
    let mut rd = CaptureReader::new(cut).unwrap();
    for want in &records()[..3] {
        assert_eq!(&rd.next_record().unwrap().unwrap(), want);
    }
    match rd.next_record() {
        Err(e @ CaptureError::TruncatedRecord { record: 3, .. }) => {
            assert!(e.to_string().contains("record 3"), "{e}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn bad_magic_is_rejected_and_an_absurd_length_is_skipped_to_the_next_valid_record() {
    assert!(matches!(
        CaptureReader::new(&b"NOTACAPTURE....."[..]),
        Err(CaptureError::BadMagic(_))
    ));
    let good = write_all();
    let hlen = u32::from_le_bytes(good[8..12].try_into().unwrap()) as usize;
    let at = 12 + hlen + 8;
    // record 0 (4 data bytes) claims 2^31 - 1 bytes, then 1000 (past the end of the file),
    // then a link reset with length bits: each time the reader skips record 0's 16 bytes and
    // goes on with record 1
    for bad in [0x7FFF_FFFFu32, 1000, LINK_RESET | 4] {
        let mut bytes = good.clone();
        bytes[at..at + 4].copy_from_slice(&bad.to_le_bytes());
        let rd = CaptureReader::new(&bytes[..]).unwrap();
        let mut rd = rd;
        let got: Vec<Record> = (&mut rd).map(|r| r.unwrap()).collect();
        assert_eq!(got, records()[1..], "length {bad:#x}");
        let rs = rd.resync_stats();
        assert_eq!(rs.resyncs, 1, "length {bad:#x}");
        assert_eq!(rs.skipped_bytes, 16, "length {bad:#x}");
        assert_eq!(rs.first, Some((0, (12 + hlen) as u64, 16)));
    }
    // an absurd length in the last record: nothing valid follows it
    let mut bytes = good.clone();
    let last = bytes.len() - 3 - 12 + 8;
    bytes[last..last + 4].copy_from_slice(&0x7FFF_FFFFu32.to_le_bytes());
    let mut rd = CaptureReader::new(&bytes[..]).unwrap();
    for want in &records()[..3] {
        assert_eq!(&rd.next_record().unwrap().unwrap(), want);
    }
    assert!(matches!(
        rd.next_record(),
        Err(CaptureError::BadRecord { record: 3, .. })
    ));
    assert!(
        rd.next_record().unwrap().is_none(),
        "an error ends the reading"
    );
}

#[test]
fn crc32c_agrees_with_the_crc_crate_catalogue_implementation() {
    use rand::{Rng, SeedableRng};
    let reference = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    for len in [0usize, 1, 2, 7, 75, 131, 1000] {
        let data: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        assert_eq!(
            nav_core::wire::crc32c(&data),
            reference.checksum(&data),
            "len {len}"
        );
    }
}

/// A zero-filled tail (a file preallocated, or extended with zeros by a crash) is no records:
/// every record before it is returned, then the first zero header is named as corrupt (not
/// each 12 zero bytes read as an empty record at time 0).
#[test]
fn a_zero_filled_tail_is_corrupt_not_empty_records() {
    let good = write_all();
    let mut bytes = good.clone();
    bytes.resize(good.len() + (1 << 20), 0);
    let mut rd = CaptureReader::new(&bytes[..]).unwrap();
    for want in &records() {
        assert_eq!(&rd.next_record().unwrap().unwrap(), want);
    }
    match rd.next_record() {
        Err(
            e @ CaptureError::BadRecord {
                record: 4,
                len: 0,
                offset,
            },
        ) => {
            assert_eq!(offset, good.len() as u64);
            assert!(e.to_string().contains("claims 0 bytes"), "{e}");
        }
        other => panic!("{other:?}"),
    }
    // a zero-filled stretch inside the file is skipped to the next record
    let hlen = u32::from_le_bytes(good[8..12].try_into().unwrap()) as usize;
    let r1 = 12 + hlen + 16;
    let mut bytes = good[..r1].to_vec();
    bytes.extend(std::iter::repeat_n(0u8, 4096));
    bytes.extend_from_slice(&good[r1..]);
    let mut rd = CaptureReader::new(&bytes[..]).unwrap();
    let got: Vec<Record> = (&mut rd).map(|r| r.unwrap()).collect();
    assert_eq!(got, records());
    assert_eq!(rd.resync_stats().skipped_bytes, 4096);
}
