use super::*;

#[test]
fn crc32_is_the_ieee_checksum() {
    // The standard check value of CRC-32/ISO-HDLC (zlib, PNG).
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(b""), 0);
}

#[test]
fn stream_header_reports_version_and_checksum() {
    let s = Sct::new(Node::Constant(2.0), 4, 4, (1.0, 1.0)).unwrap();
    let mut b = s.to_bytes().unwrap();
    let h = stream_header(&b).unwrap();
    assert!(h.is_sct);
    assert_eq!(h.version, VERSION);
    assert_eq!(h.checksum_ok, Some(true));
    let n = b.len();
    b[n - 5] ^= 1;
    assert_eq!(stream_header(&b).unwrap().checksum_ok, Some(false));
    let e = Sct::from_bytes(&b, &FunctionAtomRegistry::new()).unwrap_err();
    assert!(e.to_string().contains("checksum"), "{e}");
    assert!(stream_header(b"not a model").is_none());
}
