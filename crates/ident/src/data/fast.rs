//! The fast path of the text-table reader ([`super::read_columns_at`]): byte-level splitting of the
//! data rows with no per-line allocation, only the wanted columns parsed, plain decimals parsed by
//! an exact fast path ([`parse_plain`]), and a large table parsed in two halves on two threads.
//!
//! It gives exactly what the simple reader ([`super::read_columns_simple`]) gives, or `None`:
//! the header is read by the simple reader's own functions, a line holding anything beyond plain
//! ASCII fields (a `#` comment, a quote, a non-ASCII byte, a control character) is read by the
//! simple reader's rules for that line, and on any error (a missing field, a field that is not a
//! number, an empty file, a bad column) the caller runs the simple reader, whose message is the
//! error reported. Files whose lines end in a bare `\r` (no `\n` at all) are left to the simple
//! reader.

use super::{column_indices, delimiter, is_numeric_row, split_line, unquote, ColumnsAt};
use memchr::memchr;

/// Tables with at least this many bytes of data rows are parsed in two halves on two threads.
pub(super) const PARALLEL_BYTES: usize = 256 << 10;

/// Exact powers of ten: every `10^k` for `k <= 22` is a double without rounding.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// `s` as a double when it is a plain decimal `[+-]D[.D][(e|E)[+-]D]` (at least one mantissa
/// digit, at most 19 digits) whose value is `m 10^e` with an integer `m <= 2^53` and
/// `|e| <= 22`, else `None`.
///
/// Then `m` and `10^|e|` are exact doubles and the one IEEE multiplication or division rounds the
/// exact value correctly (Clinger's fast path, W. D. Clinger, "How to read floating point numbers
/// accurately", PLDI 1990): the value `str::parse::<f64>` (correctly rounded) gives, to the bit,
/// including the sign of zero. Everything else (more digits, larger exponents, `inf`, `NaN`, ...)
/// is left to `str::parse`.
pub(super) fn parse_plain(s: &[u8]) -> Option<f64> {
    parse_prefix(s).and_then(|(v, end)| (end == s.len()).then_some(v))
}

/// [`parse_plain`] of the longest prefix of `s` that the plain grammar reads (a prefix that ends
/// inside an exponent, such as `1e` or `1e+`, gives `None`), and where it ends.
fn parse_prefix(s: &[u8]) -> Option<(f64, usize)> {
    let n = s.len();
    let mut i = 0;
    let neg = match s.first()? {
        b'-' => {
            i = 1;
            true
        }
        b'+' => {
            i = 1;
            false
        }
        _ => false,
    };
    // At most 19 digits fit a u64: longer mantissas are left to std (checked below, the
    // wrapping arithmetic is then not used).
    let mut m: u64 = 0;
    let d0 = i;
    while i < n && s[i].is_ascii_digit() {
        m = m.wrapping_mul(10).wrapping_add(u64::from(s[i] - b'0'));
        i += 1;
    }
    let mut digits = i - d0;
    let mut exp: i64 = 0;
    if i < n && s[i] == b'.' {
        i += 1;
        let f0 = i;
        while i < n && s[i].is_ascii_digit() {
            m = m.wrapping_mul(10).wrapping_add(u64::from(s[i] - b'0'));
            i += 1;
        }
        digits += i - f0;
        exp = -((i - f0) as i64);
    }
    if digits == 0 || digits > 19 {
        return None;
    }
    if i < n && (s[i] == b'e' || s[i] == b'E') {
        i += 1;
        let eneg = match s.get(i) {
            Some(b'-') => {
                i += 1;
                true
            }
            Some(b'+') => {
                i += 1;
                false
            }
            _ => false,
        };
        let e0 = i;
        let mut e: i64 = 0;
        while i < n && s[i].is_ascii_digit() {
            if i - e0 >= 6 {
                return None;
            }
            e = e * 10 + i64::from(s[i] - b'0');
            i += 1;
        }
        if i == e0 {
            return None;
        }
        exp += if eneg { -e } else { e };
    }
    if m > 1 << 53 {
        return None;
    }
    let v = m as f64;
    let r = if m == 0 || exp == 0 {
        v
    } else if (1..=22).contains(&exp) {
        v * POW10[exp as usize]
    } else if (-22..0).contains(&exp) {
        v / POW10[(-exp) as usize]
    } else {
        return None;
    };
    Some((if neg { -r } else { r }, i))
}

/// A field's value: [`parse_plain`], else `str::parse`.
fn number(text: &str, a: usize, b: usize) -> Option<f64> {
    parse_plain(&text.as_bytes()[a..b]).or_else(|| text[a..b].parse::<f64>().ok())
}

/// Byte classes of a data line.
const PLAIN: u8 = 0;
const SPACE: u8 = 1;
const ODD: u8 = 2;

/// The class of each byte: `SPACE` for the ASCII white space `str::trim` removes and the fast
/// path handles (space, tab, `\r`), `ODD` for what only the simple rules handle (`#`, quotes,
/// other control characters, non-ASCII bytes), `PLAIN` for the other printable ASCII.
const fn classes() -> [u8; 256] {
    let mut c = [ODD; 256];
    let mut b = 0x21;
    while b < 0x7f {
        c[b] = PLAIN;
        b += 1;
    }
    c[b' ' as usize] = SPACE;
    c[b'\t' as usize] = SPACE;
    c[b'\r' as usize] = SPACE;
    c[b'#' as usize] = ODD;
    c[b'"' as usize] = ODD;
    c[b'\'' as usize] = ODD;
    c
}
static CLASS: [u8; 256] = classes();

/// Rows parsed from one part of the table.
struct Part<const N: usize> {
    cols: [Vec<f64>; N],
    lines: Vec<usize>,
    /// Physical lines in the part.
    physical: usize,
}

/// What a line gave: a row, nothing (blank or comment), or a failure (the simple reader reports).
enum Row {
    Values,
    Blank,
    Fail,
}

/// The wanted fields of the line `text[a..b]` (a physical line, its `\n` excluded) into `out`,
/// by the simple reader's rules (`#` cut, trimmed, split, unquoted, parsed).
fn simple_row<const N: usize>(
    text: &str,
    (a, b): (usize, usize),
    delim: char,
    width: usize,
    idx: &[usize; N],
    out: &mut [f64; N],
) -> Row {
    let line = text[a..b].split('#').next().unwrap_or("").trim();
    if line.is_empty() {
        return Row::Blank;
    }
    let f = split_line(line, delim);
    if f.len() != width {
        return Row::Fail;
    }
    for (o, &i) in out.iter_mut().zip(idx) {
        match f.get(i).map(|s| unquote(s).parse::<f64>()) {
            Some(Ok(v)) => *o = v,
            _ => return Row::Fail,
        }
    }
    Row::Values
}

/// The wanted fields of the line `text[a..b]` into `out`: byte-level when the line is plain ASCII
/// fields, else [`simple_row`].
fn row<const N: usize>(
    text: &str,
    (a, b): (usize, usize),
    delim: u8,
    slot: &[u8],
    wanted_end: usize,
    idx: &[usize; N],
    out: &mut [f64; N],
) -> Row {
    let bytes = text.as_bytes();
    // The line trimmed of ASCII white space (what `str::trim` removes of it, unless an odd byte
    // is at an end: then the scan below hands the line to the simple rules).
    let (mut a0, mut b0) = (a, b);
    while a0 < b0 && CLASS[bytes[a0] as usize] == SPACE {
        a0 += 1;
    }
    while b0 > a0 && CLASS[bytes[b0 - 1] as usize] == SPACE {
        b0 -= 1;
    }
    if a0 == b0 {
        return Row::Blank;
    }
    // White space inside a field (a tab that delimits is not).
    let space = |b: u8| CLASS[b as usize] == SPACE && b != delim;
    // The common row: wanted fields that are plain decimals, read as they are scanned.
    let mut k = a0;
    let mut done = true;
    for (field, &s) in slot[..wanted_end].iter().enumerate() {
        while k < b0 && space(bytes[k]) {
            k += 1;
        }
        if s != u8::MAX {
            let Some((v, used)) = parse_prefix(&bytes[k..b0]) else {
                done = false;
                break;
            };
            out[s as usize] = v;
            k += used;
            while k < b0 && space(bytes[k]) {
                k += 1;
            }
        } else {
            while k < b0 && bytes[k] != delim && CLASS[bytes[k] as usize] != ODD {
                k += 1;
            }
        }
        // The field must end here: at a delimiter, or at the line's end for the last one (the
        // row has exactly the header's fields).
        let last = field + 1 == slot.len();
        if !last && k < b0 && bytes[k] == delim {
            k += 1;
        } else if !(last && k == b0) {
            done = false;
            break;
        }
    }
    if done && wanted_end < slot.len() {
        // The fields after the last wanted one are counted, not read: as many as the header
        // has left (a `#` would cut the line: the simple rules then count).
        // Byte counters the compiler vectorises 16 or 32 at a time (a row's tail is short: no
        // per-call set-up as in memchr).
        let (mut delims, mut hash) = (0usize, 0u8);
        for chunk in bytes[k..b0].chunks(255) {
            let mut n = 0u8;
            for &c in chunk {
                n = n.wrapping_add(u8::from(c == delim)); // at most 255: no overflow
                hash |= u8::from(c == b'#');
            }
            delims += usize::from(n);
        }
        done = hash == 0 && delims + 1 == slot.len() - wanted_end;
    }
    if done {
        return Row::Values;
    }
    let mut field = 0usize;
    let mut start = a0;
    let mut filled = 0usize;
    let mut k = a0;
    loop {
        let end = k == b0;
        if end || bytes[k] == delim {
            if let Some(&s) = slot.get(field) {
                if s != u8::MAX {
                    let (mut fa, mut fb) = (start, k);
                    while fa < fb && CLASS[bytes[fa] as usize] == SPACE {
                        fa += 1;
                    }
                    while fb > fa && CLASS[bytes[fb - 1] as usize] == SPACE {
                        fb -= 1;
                    }
                    match number(text, fa, fb) {
                        Some(v) => out[s as usize] = v,
                        None => return Row::Fail,
                    }
                    filled += 1;
                }
            }
            field += 1;
            if end || field >= slot.len() {
                break;
            }
            start = k + 1;
        } else if CLASS[bytes[k] as usize] == ODD {
            return simple_row(text, (a, b), delim as char, slot.len(), idx, out);
        }
        k += 1;
    }
    // as many fields as the header: the last one ends the line; what follows it else (another
    // field, or a comment and white space the simple rules cut) is counted by the simple rules
    if filled < N {
        Row::Fail
    } else if field == slot.len() && k == b0 {
        Row::Values
    } else {
        simple_row(text, (a, b), delim as char, slot.len(), idx, out)
    }
}

/// Parse the lines of `text[a..b]` (`b` at the end of the text or just after a `\n`), the first
/// being line `first_line`.
/// `cap_bytes`: the bytes whose rows the columns are sized for at first (a hint, not a limit).
fn part<const N: usize>(
    text: &str,
    (a, b): (usize, usize),
    cap_bytes: usize,
    delim: u8,
    slot: &[u8],
    idx: &[usize; N],
    first_line: usize,
    want_lines: bool,
) -> Option<Part<N>> {
    let bytes = &text.as_bytes()[..b];
    // About 40 bytes a row for three columns.
    let guess = cap_bytes / (12 * N.max(1) + 4);
    let mut out = Part {
        cols: std::array::from_fn(|_| Vec::with_capacity(guess)),
        lines: Vec::with_capacity(if want_lines { guess } else { 0 }),
        physical: 0,
    };
    let mut vals = [0.0; N];
    // one past the last wanted field
    let wanted_end = slot
        .iter()
        .rposition(|&s| s != u8::MAX)
        .map_or(0, |i| i + 1);
    let mut pos = a;
    while pos < b {
        let end = memchr(b'\n', &bytes[pos..]).map_or(b, |i| pos + i);
        out.physical += 1;
        match row(text, (pos, end), delim, slot, wanted_end, idx, &mut vals) {
            Row::Values => {
                for (c, v) in out.cols.iter_mut().zip(vals) {
                    c.push(v);
                }
                if want_lines {
                    out.lines.push(first_line + out.physical - 1);
                }
            }
            Row::Blank => {}
            Row::Fail => return None,
        }
        pos = end + 1;
    }
    Some(out)
}

/// [`super::read_columns_at`] by the fast path, or `None` (see the module documentation); with
/// `want_lines` false the line numbers are not collected (empty). Data rows of `parallel_bytes`
/// or more are parsed in two halves on two threads.
pub(super) fn read<const N: usize>(
    text: &str,
    wants: &[&str; N],
    want_lines: bool,
    parallel_bytes: usize,
) -> Option<ColumnsAt<N>> {
    // As the simple reader: a byte-order mark skipped, lines numbered from 1.
    let bom = if text.starts_with('\u{feff}') { 3 } else { 0 };
    let bytes = text.as_bytes();
    memchr(b'\n', bytes)?;
    // The first line that holds something: the header, or the first row of a headerless file.
    let mut pos = bom;
    let mut lineno = 0usize;
    let (first_no, first_at, first, after) = loop {
        if pos >= bytes.len() {
            return None;
        }
        let end = memchr(b'\n', &bytes[pos..]).map_or(bytes.len(), |i| pos + i);
        lineno += 1;
        let content = text[pos..end].split('#').next().unwrap_or("").trim();
        if !content.is_empty() {
            break (lineno, pos, content, end + 1);
        }
        pos = end + 1;
    };
    let delim = delimiter(first);
    let fields = split_line(first, delim);
    let has_header = !is_numeric_row(&fields);
    let index_names: Vec<String>;
    let names: Vec<&str> = if has_header {
        fields.into_iter().map(unquote).collect()
    } else {
        if wants.iter().any(|w| w.parse::<usize>().is_err()) {
            return None;
        }
        index_names = (0..fields.len()).map(|i| i.to_string()).collect();
        index_names.iter().map(String::as_str).collect()
    };
    let idx: [usize; N] = column_indices(&names, wants).ok()?.try_into().ok()?;
    // Field number -> position among the wanted columns (u8::MAX: not wanted), one slot per
    // field of the header: a row must have exactly as many.
    let mut slot = vec![u8::MAX; names.len()];
    for (k, &i) in idx.iter().enumerate() {
        slot[i] = u8::try_from(k).ok()?;
    }
    let (start, start_line) = if has_header {
        (after.min(bytes.len()), first_no + 1)
    } else {
        (first_at, first_no)
    };
    let delim = u8::try_from(delim).ok()?;
    let end = bytes.len();
    let go = |range: (usize, usize), cap, line| {
        part(text, range, cap, delim, &slot, &idx, line, want_lines)
    };
    let mid = start + (end - start) / 2;
    let cut = if end - start >= parallel_bytes {
        memchr(b'\n', &bytes[mid..]).map(|i| mid + i + 1)
    } else {
        None
    };
    let mut whole = match cut {
        Some(cut) if cut < end => {
            // On two threads of the process's width (parsing runs before any fit). The second
            // half's line numbers are fixed once the first half's count is known.
            let (a, b) = crate::par::Par::available().join(
                |_| go((start, cut), end - start, start_line),
                |_| go((cut, end), end - cut, 0),
            );
            let (mut a, b) = (a?, b?);
            for (x, y) in a.cols.iter_mut().zip(&b.cols) {
                x.extend_from_slice(y);
            }
            let shift = start_line + a.physical;
            a.lines.extend(b.lines.iter().map(|l| l + shift));
            a
        }
        _ => go((start, end), end - start, start_line)?,
    };
    for c in &mut whole.cols {
        c.shrink_to_fit();
    }
    let names = names.into_iter().map(String::from).collect();
    Some((names, whole.cols, whole.lines))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn same(s: &str) {
        let want = s.parse::<f64>().ok().map(f64::to_bits);
        if let Some(v) = parse_plain(s.as_bytes()) {
            assert_eq!(Some(v.to_bits()), want, "{s:?}: {v:e}");
        }
    }

    #[test]
    fn plain_decimals_are_read_exactly() {
        for s in [
            "0",
            "-0",
            "+0",
            "-0.0",
            "0.000e0",
            "1",
            "7",
            "-3.25",
            "1.",
            ".5",
            "-.5",
            "+.5e1",
            "4.7586157502e1",
            "5.000000e-4",
            "9007199254740992",
            "9007199254740993",
            "1e22",
            "1e23",
            "1e-22",
            "1e-23",
            "0.1",
            "0.3",
            "123456789012345678",
            "1.7976931348623157e308",
            "2.2250738585072014e-308",
            "00000000000000000000000001.5",
        ] {
            same(s);
        }
        // The fast path takes these (and must give std's value, checked by `same` above).
        for s in [
            "4.7586157502e1",
            "5.000000e-4",
            "-0",
            "1.",
            ".5",
            "1e22",
            "1e-22",
        ] {
            assert!(parse_plain(s.as_bytes()).is_some(), "{s}");
        }
        assert_eq!(
            parse_plain(b"-0").map(f64::to_bits),
            Some((-0.0f64).to_bits())
        );
        // Not plain, or beyond the exact range: left to std.
        for s in [
            "",
            "-",
            ".",
            "e5",
            "1e",
            "1e+",
            "1.2.3",
            "1,5",
            " 1",
            "1 ",
            "inf",
            "NaN",
            "0x10",
            "1e23",
            "9007199254740993",
            "12345678901234567890",
            "1_0",
            "1e1000000",
        ] {
            assert!(parse_plain(s.as_bytes()).is_none(), "{s}");
        }
    }

    /// The columns as bits (`-0.0` and `0.0` differ, as they must).
    fn bits<const N: usize>(r: &ColumnsAt<N>) -> (Vec<String>, Vec<Vec<u64>>, Vec<usize>) {
        let cols =
            r.1.iter()
                .map(|c| c.iter().map(|v| v.to_bits()).collect())
                .collect();
        (r.0.clone(), cols, r.2.clone())
    }

    /// A record as `gen_data` writes it (comment, header, `t,u,y,y_clean` in its formats).
    fn generated(n: usize) -> String {
        let mut text = String::from("# a generated record\nt,u,y,y_clean\n");
        let mut x = 0.37f64;
        for k in 0..n {
            x = (x * 3.7 + 0.123).fract();
            let u = if x > 0.5 { 13 } else { 7 };
            let y = 47.7 + 20.0 * x - 10.0;
            text += &format!("{:.6e},{u},{:.10e},{:.10e}\n", k as f64 * 5e-4, y, y - 1e-3);
        }
        text
    }

    #[test]
    fn a_big_generated_file_reads_as_the_simple_reader_reads_it() {
        let text = generated(30_000);
        let simple = super::super::read_columns_simple(&text, ["t", "u", "y"]).unwrap();
        assert_eq!(simple.1[0].len(), 30_000);
        for parallel in [usize::MAX, 4096, PARALLEL_BYTES] {
            let fast = read(&text, &["t", "u", "y"], true, parallel).expect("the fast path");
            assert_eq!(bits(&fast), bits(&simple), "parallel from {parallel} bytes");
        }
        // Through the public reader (two threads: the text is over the threshold), the same.
        assert!(text.len() > PARALLEL_BYTES);
        let public = super::super::read_columns_at(&text, ["t", "u", "y"]).unwrap();
        assert_eq!(bits(&public), bits(&simple));
        // Columns chosen in another order, by index.
        let simple = super::super::read_columns_simple(&text, ["2", "0"]).unwrap();
        let fast = read(&text, &["2", "0"], true, 4096).unwrap();
        assert_eq!(bits(&fast), bits(&simple));
    }

    /// A table from tokens: fields of many shapes, delimiters, comments, quotes, blank lines,
    /// CRLF, a byte-order mark.
    fn table_text(bom: bool, delim: usize, header: usize, rows: &[(Vec<usize>, usize)]) -> String {
        const FIELDS: [&str; 24] = [
            "1",
            "-2.5",
            "3.25e-3",
            " 4 ",
            "\t5.0",
            "+6",
            ".5",
            "7.",
            "1e23",
            "-0",
            "0.1",
            "12345678901234567890",
            "nan",
            "inf",
            "\"8\"",
            "'9'",
            "x",
            "",
            " ",
            "1 2",
            "1e",
            "\u{a0}3",
            "4\u{a0}",
            "2\u{0b}",
        ];
        const ENDS: [&str; 6] = ["\n", "\r\n", "\n\n", " # note\n", "\t\n", "#\n"];
        const HEADERS: [&str; 5] = [
            "t,u,y",
            "t;u;y",
            "t\tu\ty",
            "\"t\", u ,'y'",
            "# c\n\nt,u,y,z",
        ];
        // Mostly the header's delimiter (so that columns are found by name).
        let d = [",", ";", "\t"][if header < 3 && delim < 3 {
            header
        } else {
            delim % 3
        }];
        let mut text = String::new();
        if bom {
            text.push('\u{feff}');
        }
        if header < HEADERS.len() {
            text += HEADERS[header];
            text += "\n";
        }
        for (fields, end) in rows {
            let f: Vec<&str> = fields.iter().map(|&i| FIELDS[i % FIELDS.len()]).collect();
            text += &f.join(d);
            text += ENDS[end % ENDS.len()];
        }
        text
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(6000))]

        #[test]
        fn the_fast_splitter_reads_as_the_simple_reader(
            bom in any::<bool>(),
            delim in 0usize..5,
            header in 0usize..7,
            rows in proptest::collection::vec(
                (proptest::collection::vec(
                    prop_oneof![3 => 0usize..11, 2 => 0usize..24], 1..6), 0usize..6),
                0..12),
            parallel in 1usize..64,
            which in 0usize..4,
        ) {
            let text = table_text(bom, delim, header, &rows);
            let wants: [&str; 2] = [["t", "y"], ["0", "2"], ["y", "u"], ["u", "1"]][which];
            let simple = super::super::read_columns_simple(&text, wants);
            let fast = read(&text, &wants, true, parallel);
            match (&simple, &fast) {
                (Ok(s), Some(f)) => prop_assert_eq!(bits(f), bits(s)),
                (Err(_), Some(f)) => prop_assert!(false, "fast read {:?}, simple failed", f),
                // Every table with a line feed that the simple reader reads, the fast one does.
                (Ok(_), None) => prop_assert!(!text.contains('\n')),
                (Err(_), None) => {}
            }
            // One column after another (the first field not wanted).
            let one = [["u"], ["1"]][which % 2];
            let simple = super::super::read_columns_simple(&text, one);
            match (&simple, read(&text, &one, true, parallel)) {
                (Ok(s), Some(f)) => prop_assert_eq!(bits(&f), bits(s)),
                (Err(_), Some(f)) => prop_assert!(false, "fast read {:?}, simple failed", f),
                (Ok(_), None) => prop_assert!(!text.contains('\n')),
                (Err(_), None) => {}
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]

        #[test]
        fn plain_parse_is_std_parse_on_decimal_strings(
            s in "[+-]?[0-9]{0,20}(\\.[0-9]{0,20})?([eE][+-]?[0-9]{0,4})?"
        ) {
            same(&s);
        }

        #[test]
        fn plain_parse_is_std_parse_on_printed_doubles(bits in any::<u64>(), p in 0usize..20) {
            let v = f64::from_bits(bits);
            for s in [format!("{v}"), format!("{v:e}"), format!("{v:.p$e}"), format!("{v:.p$}")] {
                same(&s);
            }
        }

        #[test]
        fn plain_parse_is_std_parse_on_any_ascii(s in "[ -~]{0,12}") {
            same(&s);
        }
    }
}
