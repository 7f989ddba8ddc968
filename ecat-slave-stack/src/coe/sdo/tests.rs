use super::*;
use crate::coe::Service;

#[test]
fn request_parse() {
    assert_eq!(
        Request::parse(&[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]),
        Ok(Request::InitiateUpload(Address {
            index: 0x1000,
            sub: 0,
            complete_access: false
        }))
    );
    assert_eq!(
        Request::parse(&[0x50, 0x12, 0x1C, 0x01, 0, 0, 0, 0]),
        Ok(Request::InitiateUpload(Address {
            index: 0x1C12,
            sub: 1,
            complete_access: true
        }))
    );
    assert_eq!(
        Request::parse(&[0x2B, 0x40, 0x60, 0x00, 0x0F, 0x00, 0xAA, 0xBB]),
        Ok(Request::InitiateDownload(InitiateDownload {
            address: Address {
                index: 0x6040,
                sub: 0,
                complete_access: false,
            },
            expedited: true,
            size_indicated: true,
            size: 0xBBAA_000F,
            data: &[0x0F, 0x00],
        }))
    );
    let b = [0x21, 0x02, 0x20, 0x00, 5, 0, 0, 0, 1, 2, 3];
    assert_eq!(
        Request::parse(&b),
        Ok(Request::InitiateDownload(InitiateDownload {
            address: Address {
                index: 0x2002,
                sub: 0,
                complete_access: false,
            },
            expedited: false,
            size_indicated: true,
            size: 5,
            data: &[1, 2, 3],
        }))
    );
    assert_eq!(
        Request::parse(&[0x0B, 1, 2, 3, 4, 5, 6, 7]),
        Ok(Request::DownloadSegment(DownloadSegment {
            toggle: false,
            last: true,
            data: &[1, 2]
        }))
    );
    assert_eq!(
        Request::parse(&[0x10, 1, 2, 3, 4, 5, 6, 7, 8]),
        Ok(Request::DownloadSegment(DownloadSegment {
            toggle: true,
            last: false,
            data: &[1, 2, 3, 4, 5, 6, 7, 8]
        }))
    );
    assert_eq!(
        Request::parse(&[0x0E, 1, 2, 3, 4, 5, 6, 7]),
        Ok(Request::DownloadSegment(DownloadSegment {
            toggle: false,
            last: false,
            data: &[]
        }))
    );
    assert_eq!(
        Request::parse(&[0x70]),
        Ok(Request::UploadSegment { toggle: true })
    );
    assert_eq!(
        Request::parse(&[0x80, 0x00, 0x10, 0x02, 0x00, 0x00, 0x04, 0x05]),
        Ok(Request::Abort {
            key: ObjectKey::new(0x1000, 2),
            code: 0x0504_0000
        })
    );
    assert_eq!(
        Request::parse(&[0xC0]),
        Ok(Request::Unknown {
            command: 0xC0,
            key: ObjectKey::new(0, 0)
        })
    );
    assert_eq!(Request::parse(&[]), Err(ErrorDetail::SizeTooShort));
    assert_eq!(
        Request::parse(&[0x40, 0, 0x10]),
        Err(ErrorDetail::SizeTooShort)
    );
    assert_eq!(
        Request::parse(&[0x00, 1, 2]),
        Err(ErrorDetail::SizeTooShort)
    );
    assert_eq!(
        Request::parse(&[0x80, 0, 0x10, 0, 0]),
        Err(ErrorDetail::SizeTooShort)
    );
}

#[test]
fn frame_view_and_emitters() {
    let f = Frame::new_unchecked(&[0x41u8, 0x08, 0x10, 0x00, 3, 0, 0, 0, b'a', b'b', b'c'][..]);
    assert_eq!(
        (f.command(), f.key(), f.data_u32()),
        (0x41, ObjectKey::new(0x1008, 0), 3)
    );
    assert_eq!(f.normal_data(), b"abc");
    let e = Frame::new_unchecked(&[][..] as &[u8]);
    assert!(e.is_empty());
    assert_eq!(e.check_len(), Err(WireError::Truncated));
    assert!(Frame::new_checked(&[0x40u8, 0, 0x10][..]).is_err());
    assert!(Frame::new_checked(&[0x60u8][..]).is_ok());
    let mut out = [0u8; 16];
    assert_eq!(
        Response::abort(ObjectKey::new(0x6040, 0), SdoAbort::ValueTooHigh).emit_coe(&mut out),
        10
    );
    assert_eq!(
        out[..10],
        [0x00, 0x20, 0x80, 0x40, 0x60, 0x00, 0x31, 0x00, 0x09, 0x06]
    );
    assert_eq!(
        Response::abort(ObjectKey::new(0, 0), SdoAbort::Timeout).emit_coe(&mut out[..9]),
        0
    );
    let seg = |toggle, last, data| Response::UploadSegment { toggle, last, data };
    assert_eq!(seg(true, true, &[9, 8]).emit_coe(&mut out), 10);
    assert_eq!(out[..10], [0x00, 0x30, 0x1B, 9, 8, 0, 0, 0, 0, 0]);
    assert_eq!(seg(false, false, &[1]).emit_coe(&mut out[..9]), 0);
    let download = Response::Download {
        key: ObjectKey::new(0x1C12, 2),
        complete_access: true,
    };
    assert_eq!(download.emit_coe(&mut out), 10);
    assert_eq!(out[..10], [0x00, 0x30, 0x70, 0x12, 0x1C, 2, 0, 0, 0, 0]);
    assert_eq!(
        Response::DownloadSegment { toggle: true }.emit_coe(&mut out),
        10
    );
    assert_eq!(out[..10], [0x00, 0x30, 0x30, 0, 0, 0, 0, 0, 0, 0]);
}

#[test]
fn response_round_trips() {
    let cases: [&[u8]; 7] = [
        &[0x60, 0x40, 0x60, 0x00, 0, 0, 0, 0],
        &[0x70, 0x12, 0x1C, 0x02, 0, 0, 0, 0],
        &[0x30, 0, 0, 0, 0, 0, 0, 0],
        &[0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0, 0],
        &[0x51, 0x00, 0x1C, 0x00, 5, 0, 0, 0, 4, 1, 2],
        &[0x1B, 9, 8, 0, 0, 0, 0, 0],
        &[0x80, 0x40, 0x60, 0x00, 0x31, 0x00, 0x09, 0x06],
    ];
    for bytes in cases {
        let r = Response::parse(&Frame::new_unchecked(bytes)).unwrap();
        assert_eq!(r.buffer_len(), bytes.len());
        let mut out = [0xEEu8; 16];
        assert_eq!(r.emit(&mut Frame::new_unchecked(&mut out[..])), bytes.len());
        assert_eq!(&out[..bytes.len()], bytes);
        assert_eq!(
            r.emit(&mut Frame::new_unchecked(&mut out[..bytes.len() - 1])),
            0
        );
    }
    assert_eq!(
        Response::parse(&Frame::new_unchecked(&[
            0x4B, 0x41, 0x60, 0x00, 0x37, 0x02, 0, 0
        ])),
        Ok(Response::UploadExpedited {
            key: ObjectKey::new(0x6041, 0),
            data: &[0x37, 0x02]
        })
    );
    assert_eq!(
        Response::parse(&Frame::new_unchecked(&[0x60, 0x40, 0x60][..])),
        Err(WireError::Truncated)
    );
    assert_eq!(
        Response::parse(&Frame::new_unchecked(&[0xA0, 0, 0, 0, 0, 0, 0, 0][..])),
        Err(WireError::UnknownCommand(0xA0))
    );
    assert_eq!(
        Response::abort(ObjectKey::new(0x1000, 0), SdoAbort::Timeout).service(),
        Service::SdoRequest
    );
    assert_eq!(
        Response::DownloadSegment { toggle: false }.service(),
        Service::SdoResponse
    );
}

#[test]
fn request_frame_checks() {
    for short in [
        &[][..],
        &[0x40, 0, 0x10][..],
        &[0x23, 0, 0x60, 0, 1, 2, 3][..],
    ] {
        assert_eq!(Frame::new_checked(short).unwrap_err(), WireError::Truncated);
        assert_eq!(Request::parse(short), Err(ErrorDetail::SizeTooShort));
    }
    assert!(Frame::new_checked(&[0x60u8][..]).is_ok());
    assert_eq!(
        Request::parse(&[0xC0, 0x34]),
        Ok(Request::Unknown {
            command: 0xC0,
            key: ObjectKey::new(0x34, 0)
        })
    );
}

#[test]
fn bit_helpers() {
    let mut b = [0xFFu8; 3];
    put_bits(&mut b, 3, 0b1010, 4);
    assert_eq!(b[0], 0b1101_0111);
    assert_eq!(get_bits(&b, 3, 4), 0b1010);
    put_bits(&mut b, 6, 0, 6);
    assert_eq!(b[..2], [0b0001_0111, 0b1111_0000]);
    assert_eq!(get_bits(&b, 20, 8), 0x0F); // bits past the end read 0
    put_bits(&mut b, 22, 0xFF, 8); // writes past the end are dropped
    assert_eq!(b[2], 0xFF);
}
