//! The Rust codec against the description of the frames (`drive::protocol::spec`): for the shared
//! vectors' frames and for random messages, every field the table names sits at its offset with
//! its width and holds the value the message's own struct field (named alike, read from its
//! `Debug` form) holds; reserved bytes are 0; no struct field is missing from the table; the
//! payload is exactly as long as the table says.

use drive::protocol::spec::{self, MessageSpec, Wire};
use drive::protocol::{DriveState, EndReason, Message, NakCode};
use proptest::prelude::*;

/// Split `s` at the commas outside brackets and parentheses.
fn split_top(s: &str) -> Vec<&str> {
    let (mut out, mut depth, mut from) = (vec![], 0i32, 0);
    for (k, ch) in s.char_indices() {
        match ch {
            '[' | '(' | '{' => depth += 1,
            ']' | ')' | '}' => depth -= 1,
            ',' if depth == 0 => {
                out.push(s[from..k].trim());
                from = k + 1;
            }
            _ => {}
        }
    }
    if !s[from..].trim().is_empty() {
        out.push(s[from..].trim());
    }
    out
}

/// The message's fields as its `Debug` form names them: `Variant(Struct { name: value, .. })`,
/// or one unnamed value for `Variant(value)`, none for a unit variant.
fn debug_fields(msg: &Message) -> Vec<(String, String)> {
    let d = format!("{msg:?}");
    let Some(open) = d.find('(') else {
        return vec![];
    };
    let inner = &d[open + 1..d.len() - 1];
    match inner.find(" { ") {
        Some(b) => split_top(&inner[b + 3..inner.len() - 2])
            .into_iter()
            .map(|kv| {
                let (k, v) = kv.split_once(": ").expect("name: value");
                (k.to_string(), v.to_string())
            })
            .collect(),
        None => vec![(String::new(), inner.to_string())],
    }
}

/// A field's value from its `Debug` text: a number, or an enum's wire code (the code whose
/// value prints alike).
fn value_of(name: &str, text: &str) -> i64 {
    if let Ok(v) = text.parse::<i64>() {
        return v;
    }
    let shown = |c: u8| match name {
        "state" => DriveState::from_code(c).map(|s| format!("{s:?}")),
        "code" => Some(format!("{:?}", NakCode::from_code(c))),
        "reason" => Some(format!("{:?}", EndReason::from_code(c))),
        _ => None,
    };
    (0..=255u8)
        .find(|&c| shown(c).as_deref() == Some(text))
        .unwrap_or_else(|| panic!("{name}: no code shows as {text}")) as i64
}

/// The value of `wire` at `at` in `p`.
fn read(p: &[u8], at: usize, wire: Wire) -> i64 {
    let b = &p[at..at + wire.size()];
    match wire {
        Wire::U8 | Wire::Reserved => b[0] as i64,
        Wire::U16 => u16::from_le_bytes([b[0], b[1]]) as i64,
        Wire::I16 => i16::from_le_bytes([b[0], b[1]]) as i64,
        Wire::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64,
        Wire::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64,
    }
}

/// The samples of a DATA block from its `Debug` text `[[u, y, i], ..]`.
fn samples_of(text: &str) -> Vec<Vec<i64>> {
    let t = text.trim().trim_start_matches('[').trim_end_matches(']');
    t.split("], [")
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.trim_matches(|c| c == '[' || c == ']')
                .split(", ")
                .map(|v| v.parse().expect("a sample value"))
                .collect()
        })
        .collect()
}

/// Check one message's payload against its row of the table.
fn check(msg: &Message) {
    check_against(
        msg,
        spec::message(msg.type_code()).expect("every type is in the table"),
    );
}

/// Check one message's payload against a row of a table.
fn check_against(msg: &Message, spec: &MessageSpec) {
    let mut p = Vec::new();
    msg.write_payload(&mut p);
    let what = format!("{} {msg:?}", spec.name);
    assert_eq!(Some(p.len()), spec.payload_len(&p), "{what}: length");
    let fields = debug_fields(msg);
    let named = |n: &str| {
        fields
            .iter()
            .find(|(k, _)| k == n || (k.is_empty() && spec.fields.len() == 1))
            .map(|(_, v)| v.as_str())
    };
    for (k, _) in &fields {
        assert!(
            k.is_empty() || k == "samples" || spec.fields.iter().any(|f| f.name == k),
            "{what}: the struct's field {k} is not in the table"
        );
    }
    let samples = named("samples").map(samples_of);
    for (at, f) in spec.layout() {
        let wire = read(&p, at, f.wire);
        let want = match (f.wire, f.name, &samples) {
            (Wire::Reserved, _, _) => 0,
            (_, "n", Some(s)) => s.len() as i64,
            _ => value_of(
                f.name,
                named(f.name).unwrap_or_else(|| panic!("{what}: no field {}", f.name)),
            ),
        };
        assert_eq!(wire, want, "{what}: {} at offset {at}", f.name);
    }
    for (k, rec) in samples.iter().flatten().enumerate() {
        let mut at = spec.fixed_len() + k * spec.record_len();
        for (j, f) in spec.repeated.iter().enumerate() {
            assert_eq!(
                read(&p, at, f.wire),
                rec[j],
                "{what}: sample {k} {}",
                f.name
            );
            at += f.wire.size();
        }
    }
}

#[test]
fn the_vectors_frames_are_laid_out_as_the_table_says() {
    let frames = crate::vectors::named_frames();
    for (_, f) in &frames {
        check(&f.msg);
    }
    // every message of the table has a vector
    for m in spec::MESSAGES {
        assert!(
            frames.iter().any(|(_, f)| f.msg.type_code() == m.code),
            "no vector of {}",
            m.name
        );
    }
}

#[test]
fn a_table_with_two_fields_swapped_fails_the_check() {
    // CONFIGURE's speed and voltage limits (24000, 30000 raw by default) swapped in the table
    let spec = spec::message(drive::protocol::ty::CONFIGURE).expect("CONFIGURE");
    let mut fields = spec.fields.to_vec();
    let at = |n: &str| fields.iter().position(|f| f.name == n).expect(n);
    let (u, y) = (at("u_limit"), at("y_limit"));
    fields.swap(u, y);
    let swapped = MessageSpec {
        fields: Box::leak(fields.into_boxed_slice()),
        ..*spec
    };
    let msg = Message::Configure(drive::protocol::Configure::default());
    check_against(&msg, spec);
    let caught = std::panic::catch_unwind(|| check_against(&msg, &swapped));
    assert!(caught.is_err(), "the swap went unnoticed");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]
    #[test]
    fn random_messages_are_laid_out_as_the_table_says(msg in crate::props::arb_msg()) {
        check(&msg);
    }
}
