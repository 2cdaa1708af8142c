//! The IPP wire format checked where the `ipp` crate would not check it: any message, a
//! client's request, a spooled request or a printer's response, passes here before the
//! crate parses it. No other part of the server is used, so every part may use this.

/// Checks the values of an IPP message's attributes that the `ipp` crate (8.0) would read
/// past their end: a `textWithLanguage` or `nameWithLanguage` value (tags 0x35, 0x36) is
/// two length-prefixed strings, and the crate slices the second by its claimed length
/// without checking it against the value, which panics. Everything else is left to the
/// parser, which reports a truncated message as an error; so is a message cut short here.
pub fn check_wire(bytes: &[u8]) -> Result<(), String> {
    let u16_at = |i: usize| -> Option<usize> {
        Some(usize::from(u16::from_be_bytes([
            *bytes.get(i)?,
            *bytes.get(i + 1)?,
        ])))
    };
    // The version, operation or status, and request-id.
    let mut i = 8;
    while let Some(&tag) = bytes.get(i) {
        i += 1;
        if tag == 0x03 {
            break;
        }
        if tag < 0x10 {
            continue;
        }
        let Some(name_len) = u16_at(i) else {
            return Ok(());
        };
        i += 2 + name_len;
        let Some(value_len) = u16_at(i) else {
            return Ok(());
        };
        i += 2;
        let Some(value) = bytes.get(i..i + value_len) else {
            return Ok(());
        };
        if tag == 0x35 || tag == 0x36 {
            let fits = |at: usize| {
                let n = value.get(at..at + 2)?;
                let end = at + 2 + usize::from(u16::from_be_bytes([n[0], n[1]]));
                (end <= value.len()).then_some(end)
            };
            if fits(0).and_then(fits).is_none() {
                return Err(format!(
                    "a {} value's language or text runs past the value's {value_len} bytes",
                    if tag == 0x35 {
                        "textWithLanguage"
                    } else {
                        "nameWithLanguage"
                    }
                ));
            }
        }
        i += value_len;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_wire_refuses_what_the_parser_would_read_past() {
        let head = [2u8, 0, 0, 0x0b, 0, 0, 0, 1, 0x01];
        let value = |tag: u8, v: &[u8]| -> Vec<u8> {
            let mut b = head.to_vec();
            b.extend([tag, 0, 1, b'n']);
            b.extend((v.len() as u16).to_be_bytes());
            b.extend(v);
            b.push(0x03);
            b
        };
        // "en" then "hi": well formed.
        let good = [0, 2, b'e', b'n', 0, 2, b'h', b'i'];
        assert!(check_wire(&value(0x35, &good)).is_ok());
        assert!(check_wire(&value(0x36, &good)).is_ok());
        // The text claims 5 bytes of 2; the language claims 9 of 6; no second length.
        for bad in [
            &[0, 2, b'e', b'n', 0, 5, b'h', b'i'][..],
            &[0, 9, b'e', b'n', 0, 2, b'h', b'i'],
            &[0, 2, b'e', b'n'],
            &[0],
        ] {
            let msg = check_wire(&value(0x35, bad)).unwrap_err();
            assert!(msg.contains("textWithLanguage"), "{msg}");
            assert!(check_wire(&value(0x36, bad)).is_err());
            // The same bytes as plain text are no concern of this check.
            assert!(check_wire(&value(0x41, bad)).is_ok());
        }
        // A message cut short is the parser's to report.
        assert!(check_wire(&value(0x35, &good)[..14]).is_ok());
        assert!(check_wire(&[]).is_ok());
        // Each refused message would have panicked in the parser; each accepted one parses.
        let parse = |b: Vec<u8>| {
            ipp::parser::IppParser::new(ipp::reader::IppReader::new(std::io::Cursor::new(b)))
                .parse()
        };
        assert!(parse(value(0x35, &good)).is_ok());
    }
}
