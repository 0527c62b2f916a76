//! TensorBoard event files: the epoch scalars, so that `tensorboard --logdir runs` plots every
//! run. `progress.csv` stays the canonical record; the event files are a view of it.
//!
//! An event file (`events.out.tfevents.<secs>.<hostname>`) is a sequence of TFRecords, each
//!
//! ```text
//! u64 LE length | u32 LE masked CRC32C(length bytes) | data | u32 LE masked CRC32C(data)
//! ```
//!
//! with `mask(c) = ((c >> 15) | (c << 17)) + 0xa282ead8` (wrapping), around one protobuf `Event`:
//!
//! ```text
//! Event   { double wall_time = 1; int64 step = 2; string file_version = 3; Summary summary = 5; }
//! Summary { repeated Value value = 1; }
//! Value   { string tag = 1; float simple_value = 2; }
//! ```
//!
//! The first event carries only `file_version = "brain.Event:2"`; each later one the scalars of
//! one step. The messages are encoded here by hand, because no crate fits: `tensorboard-rs`
//! (last release 2022, repository marked inactive) pulls in protobuf 2 and image 0.23;
//! `tboard` (one release, 2023) needs `protoc` at build time through prost-build; and
//! `syntaxdot-summary` (prost 0.9) belongs to an unrelated, dormant project. Writing scalars
//! needs three small messages and the framing above, checked against an independent reader in
//! the tests and against TensorBoard's own loader by `scripts/check_tensorboard.py`.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, ErrorKind, Write};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use anyhow::Context;

use crate::progress_csv::ProgressRow;

/// The `file_version` of the first event, which tells TensorBoard the format version.
const FILE_VERSION: &str = "brain.Event:2";

/// How many numbered alternatives [`EventWriter::create`] tries when the file name is taken.
const MAX_NAME_TRIES: u32 = 1000;

/// Writes one TensorBoard event file; every call to [`EventWriter::scalars`] is on disk when it
/// returns.
#[derive(Debug)]
pub struct EventWriter {
    file: BufWriter<File>,
    path: PathBuf,
}

impl EventWriter {
    /// Creates `dir` if needed and a new event file in it, named like TensorBoard's own
    /// (`events.out.tfevents.<unix secs>.<hostname>`, with `.1`, `.2`, … appended when that name
    /// is taken: an existing file is never overwritten), and writes the file-version event.
    pub fn create(dir: &Path) -> anyhow::Result<Self> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        let host: String = gethostname::gethostname()
            .to_string_lossy()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        let base = format!("events.out.tfevents.{}.{host}", now.as_secs());
        let (file, path) = create_new(dir, &base)?;
        let mut writer = Self {
            file: BufWriter::new(file),
            path,
        };
        writer.write_record(&version_event(now.as_secs_f64()))?;
        Ok(writer)
    }

    /// The event file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes one event with the scalars `values` (tag, value) at `step`, stamped `wall_time`
    /// (seconds since the Unix epoch), and syncs the file. Values are stored as `f32`, as
    /// TensorBoard's `simple_value` is; NaN and infinities are written as they are.
    pub fn scalars(
        &mut self,
        step: u64,
        wall_time: f64,
        values: &[(&str, f64)],
    ) -> anyhow::Result<()> {
        let step = i64::try_from(step)
            .with_context(|| format!("step {step} does not fit TensorBoard's int64"))?;
        self.write_record(&scalars_event(wall_time, step, values))
    }

    /// Writes one event with the image `encoded` (a PNG or a GIF file's bytes; TensorBoard's
    /// Images tab plays an animated GIF, as tensorboardX's videos are stored) of
    /// `width × height` RGB pixels under `tag` at `step`, and syncs the file.
    pub fn image(
        &mut self,
        step: u64,
        wall_time: f64,
        tag: &str,
        (width, height): (u32, u32),
        encoded: &[u8],
    ) -> anyhow::Result<()> {
        let step = i64::try_from(step)
            .with_context(|| format!("step {step} does not fit TensorBoard's int64"))?;
        self.write_record(&image_event(wall_time, step, tag, (width, height), encoded))
    }

    /// Frames `data` as a TFRecord, appends it and syncs the file's data to disk.
    fn write_record(&mut self, data: &[u8]) -> anyhow::Result<()> {
        let context = || format!("cannot write {}", self.path.display());
        let length = (data.len() as u64).to_le_bytes();
        self.file.write_all(&length).with_context(context)?;
        self.file
            .write_all(&masked_crc(&length).to_le_bytes())
            .with_context(context)?;
        self.file.write_all(data).with_context(context)?;
        self.file
            .write_all(&masked_crc(data).to_le_bytes())
            .with_context(context)?;
        self.file.flush().with_context(context)?;
        self.file.get_ref().sync_data().with_context(context)
    }
}

/// The TensorBoard scalars of an epoch's row, grouped by tag prefix; the fields that are `None`
/// (no episode ended, or not the algorithm's) are left out. The trainer writes them at `step = row.env_steps`.
/// The line-search outcome, a string, stays in `progress.csv` only.
pub fn row_scalars(row: &ProgressRow) -> Vec<(&'static str, f64)> {
    let optional = [
        ("return/mean", row.ep_ret_mean),
        ("return/min", row.ep_ret_min),
        ("return/max", row.ep_ret_max),
        ("return/std", row.ep_ret_std),
        ("return/cvar10", row.ep_ret_cvar10),
        ("return/q10", row.ep_ret_q10),
        ("eval/mean", row.eval_ret_mean),
        ("eval/min", row.eval_ret_min),
        ("eval/cvar10", row.eval_ret_cvar10),
        ("eval/std", row.eval_ret_std),
        ("eval/length", row.eval_len_mean),
        ("episode/length", row.ep_len_mean),
        ("episode/success_rate", row.success_rate),
        ("bound/value", row.bound),
        ("bound/confidence", row.confidence),
        ("apo/mean_variance", row.mean_variance),
        ("apo/variance_mean", row.variance_mean),
        ("apo/bias", row.bias),
        (
            "apo/min_j_sq_on",
            row.min_j_sq_on.map(|on| f64::from(u8::from(on))),
        ),
        ("update/pi_steps", row.pi_steps.map(|s| s as f64)),
        ("update/ratio_deviation", row.ratio_deviation),
        ("vmpo/eta", row.eta),
        ("vmpo/alpha", row.alpha),
        (
            "line_search/rejected_kl",
            row.ls_rejected_kl.map(|n| n as f64),
        ),
        (
            "line_search/rejected_objective",
            row.ls_rejected_objective.map(|n| n as f64),
        ),
    ];
    let always = [
        ("episode/count", row.episodes as f64),
        ("episode/unstable", row.unstable_episodes as f64),
        ("policy/kl", row.kl),
        ("policy/entropy", row.entropy),
        ("loss/pi", row.loss_pi),
        ("loss/v", row.loss_v),
        ("apo/mean_surr", row.mean_surr),
        ("progress/env_steps", row.env_steps as f64),
        ("progress/time_s", row.time_s),
        ("speed/steps_per_s", row.steps_per_s),
        ("time/rollout_s", row.rollout_s),
        ("time/sim_s", row.sim_s),
        ("time/update_pi_s", row.update_pi_s),
        ("time/update_v_s", row.update_v_s),
        ("time/eval_s", row.eval_s),
    ];
    optional
        .into_iter()
        .filter_map(|(tag, value)| value.map(|v| (tag, v)))
        .chain(always)
        .collect()
}

/// Opens `dir/base`, or `dir/base.1`, `dir/base.2`, … for the first name not taken, failing
/// rather than truncating an existing file.
fn create_new(dir: &Path, base: &str) -> anyhow::Result<(File, PathBuf)> {
    for n in 0..MAX_NAME_TRIES {
        let path = if n == 0 {
            dir.join(base)
        } else {
            dir.join(format!("{base}.{n}"))
        };
        match OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(file) => return Ok((file, path)),
            Err(e) if e.kind() == ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e).with_context(|| format!("cannot create {}", path.display())),
        }
    }
    anyhow::bail!(
        "{}: {MAX_NAME_TRIES} event files named {base}* already exist",
        dir.display()
    )
}

/// CRC32C of `bytes`, masked as TFRecord stores it.
fn masked_crc(bytes: &[u8]) -> u32 {
    let crc = crc32c::crc32c(bytes);
    crc.rotate_right(15).wrapping_add(0xa282_ead8)
}

/// Protobuf wire types.
const VARINT: u8 = 0;
const FIXED64: u8 = 1;
const LENGTH_DELIMITED: u8 = 2;
const FIXED32: u8 = 5;

fn put_varint(buf: &mut Vec<u8>, mut value: u64) {
    while value >= 0x80 {
        buf.push((value as u8) | 0x80);
        value >>= 7;
    }
    buf.push(value as u8);
}

/// A field key; the field numbers used here are below 16, so the key is one byte.
fn put_key(buf: &mut Vec<u8>, field: u8, wire_type: u8) {
    buf.push((field << 3) | wire_type);
}

fn put_bytes(buf: &mut Vec<u8>, field: u8, bytes: &[u8]) {
    put_key(buf, field, LENGTH_DELIMITED);
    put_varint(buf, bytes.len() as u64);
    buf.extend_from_slice(bytes);
}

/// `Event { wall_time, file_version: "brain.Event:2" }`.
fn version_event(wall_time: f64) -> Vec<u8> {
    let mut event = Vec::new();
    put_key(&mut event, 1, FIXED64);
    event.extend_from_slice(&wall_time.to_le_bytes());
    put_bytes(&mut event, 3, FILE_VERSION.as_bytes());
    event
}

/// `Event { wall_time, step, summary: Summary { value: [Value { tag, simple_value }, …] } }`.
fn scalars_event(wall_time: f64, step: i64, values: &[(&str, f64)]) -> Vec<u8> {
    let mut summary = Vec::new();
    let mut value = Vec::new();
    for (tag, v) in values {
        value.clear();
        put_bytes(&mut value, 1, tag.as_bytes());
        put_key(&mut value, 2, FIXED32);
        value.extend_from_slice(&(*v as f32).to_le_bytes());
        put_bytes(&mut summary, 1, &value);
    }
    summary_event(wall_time, step, &summary)
}

/// `Event { wall_time, step, summary }` of an encoded `Summary`.
fn summary_event(wall_time: f64, step: i64, summary: &[u8]) -> Vec<u8> {
    let mut event = Vec::new();
    put_key(&mut event, 1, FIXED64);
    event.extend_from_slice(&wall_time.to_le_bytes());
    put_key(&mut event, 2, VARINT);
    // int64 is encoded as its two's-complement bits; `step` is never negative here.
    put_varint(&mut event, step as u64);
    put_bytes(&mut event, 5, summary);
    event
}

/// `Event { wall_time, step, summary: Summary { value: [Value { tag, image: Image { height,
/// width, colorspace: 3 (RGB), encoded_image_string } }] } }`.
fn image_event(
    wall_time: f64,
    step: i64,
    tag: &str,
    (width, height): (u32, u32),
    encoded: &[u8],
) -> Vec<u8> {
    let mut image = Vec::new();
    put_key(&mut image, 1, VARINT);
    put_varint(&mut image, u64::from(height));
    put_key(&mut image, 2, VARINT);
    put_varint(&mut image, u64::from(width));
    put_key(&mut image, 3, VARINT);
    put_varint(&mut image, 3);
    put_bytes(&mut image, 4, encoded);
    let mut value = Vec::new();
    put_bytes(&mut value, 1, tag.as_bytes());
    put_bytes(&mut value, 4, &image);
    let mut summary = Vec::new();
    put_bytes(&mut summary, 1, &value);
    summary_event(wall_time, step, &summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bitwise CRC32C (Castagnoli, reflected polynomial 0x82F63B78), independent of the crate.
    fn reference_crc32c(bytes: &[u8]) -> u32 {
        let mut crc = !0u32;
        for &byte in bytes {
            crc ^= u32::from(byte);
            for _ in 0..8 {
                crc = if crc & 1 == 1 {
                    (crc >> 1) ^ 0x82F6_3B78
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }

    fn reference_masked(bytes: &[u8]) -> u32 {
        let crc = reference_crc32c(bytes);
        crc.rotate_right(15).wrapping_add(0xa282_ead8)
    }

    fn u32_at(bytes: &[u8], at: usize) -> u32 {
        u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
    }

    /// Splits a file into its records, checking both CRCs of each.
    fn read_records(bytes: &[u8]) -> Vec<Vec<u8>> {
        let mut records = Vec::new();
        let mut at = 0;
        while at < bytes.len() {
            let length_bytes = &bytes[at..at + 8];
            let length = u64::from_le_bytes(length_bytes.try_into().unwrap()) as usize;
            assert_eq!(
                u32_at(bytes, at + 8),
                reference_masked(length_bytes),
                "length CRC of record {}",
                records.len()
            );
            let data = &bytes[at + 12..at + 12 + length];
            assert_eq!(
                u32_at(bytes, at + 12 + length),
                reference_masked(data),
                "data CRC of record {}",
                records.len()
            );
            records.push(data.to_vec());
            at += 12 + length + 4;
        }
        assert_eq!(at, bytes.len(), "trailing bytes");
        records
    }

    /// One protobuf field's payload.
    #[derive(Debug)]
    enum Field {
        Varint(u64),
        Fixed64([u8; 8]),
        Bytes(Vec<u8>),
        Fixed32([u8; 4]),
    }

    fn read_varint(bytes: &[u8], at: &mut usize) -> u64 {
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = bytes[*at];
            *at += 1;
            value |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                return value;
            }
        }
        panic!("varint longer than 10 bytes");
    }

    /// Decodes a message into its (field number, payload) pairs.
    fn read_fields(bytes: &[u8]) -> Vec<(u64, Field)> {
        let mut fields = Vec::new();
        let mut at = 0;
        while at < bytes.len() {
            let key = read_varint(bytes, &mut at);
            let field = match key & 7 {
                0 => Field::Varint(read_varint(bytes, &mut at)),
                1 => {
                    at += 8;
                    Field::Fixed64(bytes[at - 8..at].try_into().unwrap())
                }
                2 => {
                    let length = read_varint(bytes, &mut at) as usize;
                    at += length;
                    Field::Bytes(bytes[at - length..at].to_vec())
                }
                5 => {
                    at += 4;
                    Field::Fixed32(bytes[at - 4..at].try_into().unwrap())
                }
                other => panic!("unexpected wire type {other}"),
            };
            fields.push((key >> 3, field));
        }
        fields
    }

    /// An `Event` decoded back.
    #[derive(Debug, Default)]
    struct Decoded {
        wall_time: f64,
        step: i64,
        file_version: Option<String>,
        values: Vec<(String, f32)>,
    }

    fn decode_event(bytes: &[u8]) -> Decoded {
        let mut event = Decoded::default();
        for (number, field) in read_fields(bytes) {
            match (number, field) {
                (1, Field::Fixed64(b)) => event.wall_time = f64::from_le_bytes(b),
                (2, Field::Varint(v)) => event.step = v as i64,
                (3, Field::Bytes(b)) => event.file_version = Some(String::from_utf8(b).unwrap()),
                (5, Field::Bytes(summary)) => {
                    for (number, value) in read_fields(&summary) {
                        let Field::Bytes(value) = value else {
                            panic!("Summary.value is not a message")
                        };
                        assert_eq!(number, 1, "Summary field");
                        let (mut tag, mut simple) = (None, None);
                        for field in read_fields(&value) {
                            match field {
                                (1, Field::Bytes(b)) => tag = Some(String::from_utf8(b).unwrap()),
                                (2, Field::Fixed32(b)) => simple = Some(f32::from_le_bytes(b)),
                                other => panic!("unexpected Value field {other:?}"),
                            }
                        }
                        event.values.push((tag.unwrap(), simple.unwrap()));
                    }
                }
                other => panic!("unexpected Event field {other:?}"),
            }
        }
        event
    }

    fn decode_file(path: &Path) -> Vec<Decoded> {
        read_records(&std::fs::read(path).unwrap())
            .iter()
            .map(|r| decode_event(r))
            .collect()
    }

    #[test]
    fn reference_crc_matches_the_known_vector_and_the_crate() {
        assert_eq!(reference_crc32c(b"123456789"), 0xE306_9283);
        assert_eq!(crc32c::crc32c(b"123456789"), 0xE306_9283);
        assert_eq!(masked_crc(b"123456789"), reference_masked(b"123456789"));
    }

    #[test]
    fn writes_the_version_event_then_one_event_per_call() {
        let dir = tempfile::tempdir().unwrap();
        let mut writer = EventWriter::create(&dir.path().join("run")).unwrap();
        let name = writer
            .path()
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        assert!(name.starts_with("events.out.tfevents."), "{name}");
        writer
            .scalars(
                1,
                1_700_000_000.5,
                &[("return/mean", -12.25), ("loss/v", f64::NAN)],
            )
            .unwrap();
        writer
            .scalars(
                300,
                1_700_000_001.0,
                &[("return/mean", 1e40), ("return/min", -0.1)],
            )
            .unwrap();
        // Everything is on disk while the writer is still open.
        let events = decode_file(writer.path());
        assert_eq!(events.len(), 3);
        assert_eq!(events[0].file_version.as_deref(), Some("brain.Event:2"));
        assert!(events[0].wall_time > 1.6e9 && events[0].values.is_empty());
        assert_eq!((events[1].step, events[1].wall_time), (1, 1_700_000_000.5));
        assert_eq!(events[1].values[0], ("return/mean".to_string(), -12.25));
        assert_eq!(events[1].values[1].0, "loss/v");
        assert!(events[1].values[1].1.is_nan());
        assert_eq!(events[2].step, 300);
        assert_eq!(
            events[2].values,
            [
                ("return/mean".to_string(), f32::INFINITY),
                ("return/min".to_string(), -0.1f32)
            ]
        );
        assert!(events[1..].iter().all(|e| e.file_version.is_none()));
    }

    #[test]
    fn never_overwrites_an_existing_file() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("events.out.tfevents.1.host"), b"keep").unwrap();
        let (_, path) = create_new(dir.path(), "events.out.tfevents.1.host").unwrap();
        assert_eq!(path, dir.path().join("events.out.tfevents.1.host.1"));
        assert_eq!(
            std::fs::read(dir.path().join("events.out.tfevents.1.host")).unwrap(),
            b"keep"
        );
        // Two writers in the same second get two files.
        let a = EventWriter::create(dir.path()).unwrap();
        let b = EventWriter::create(dir.path()).unwrap();
        assert_ne!(a.path(), b.path());
        assert_eq!(decode_file(a.path()).len(), 1);
        assert_eq!(decode_file(b.path()).len(), 1);
    }

    fn row(stats: bool) -> ProgressRow {
        let some = |v: f64| stats.then_some(v);
        ProgressRow {
            epoch: 3,
            env_steps: 12_000,
            episodes: if stats { 4 } else { 0 },
            ep_ret_mean: some(-150.0),
            ep_ret_min: some(-300.0),
            ep_ret_max: some(-10.0),
            ep_ret_std: some(90.0),
            ep_ret_cvar10: some(-280.0),
            ep_ret_q10: some(-270.0),
            ep_len_mean: some(200.0),
            success_rate: None,
            bound: some(-400.0),
            confidence: some(0.7),
            kl: 0.01,
            entropy: 1.4,
            loss_pi: -0.2,
            loss_v: 35.0,
            mean_surr: 0.3,
            mean_variance: None,
            variance_mean: Some(2.0),
            line_search: Some("accepted:0".to_string()),
            ls_rejected_kl: None,
            ls_rejected_objective: None,
            bias: None,
            min_j_sq_on: None,
            pi_steps: None,
            ratio_deviation: None,
            eta: None,
            alpha: None,
            unstable_episodes: 0,
            eval_ret_mean: None,
            eval_ret_min: None,
            eval_ret_cvar10: None,
            eval_ret_std: None,
            eval_len_mean: None,
            eval_unstable_episodes: None,
            steps_per_s: 1500.0,
            time_s: 8.0,
            rollout_s: 1.0,
            update_pi_s: 2.0,
            update_v_s: 3.0,
            eval_s: 0.0,
            sim_s: 0.75,
        }
    }

    #[test]
    fn row_scalars_keeps_the_fields_that_are_set() {
        let full = row_scalars(&row(true));
        let get = |tag: &str| full.iter().find(|(t, _)| *t == tag).map(|(_, v)| *v);
        assert_eq!(get("return/mean"), Some(-150.0));
        assert_eq!(get("return/cvar10"), Some(-280.0));
        assert_eq!(get("return/q10"), Some(-270.0));
        assert_eq!(get("bound/confidence"), Some(0.7));
        assert_eq!(get("apo/variance_mean"), Some(2.0));
        assert_eq!(get("speed/steps_per_s"), Some(1500.0));
        assert_eq!(get("time/sim_s"), Some(0.75));
        assert_eq!(get("apo/mean_variance"), None);
        assert_eq!(get("update/pi_steps"), None);
        let mut tags: Vec<_> = full.iter().map(|(t, _)| *t).collect();
        tags.sort_unstable();
        tags.dedup();
        assert_eq!(tags.len(), full.len(), "tags are unique");

        let empty = row_scalars(&row(false));
        assert!(empty
            .iter()
            .all(|(t, _)| !t.starts_with("return/") && !t.starts_with("bound/")));
        assert!(empty
            .iter()
            .any(|(t, v)| *t == "episode/count" && *v == 0.0));
        assert_eq!(full.len() - empty.len(), 9);
    }

    #[test]
    fn writes_an_image_summary_with_its_size_and_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let mut writer = EventWriter::create(dir.path()).unwrap();
        let gif = b"GIF89a not really a gif";
        writer
            .image(4_000, 1_700_000_002.0, "video/eval", (320, 240), gif)
            .unwrap();
        let bytes = std::fs::read(writer.path()).unwrap();
        let records = read_records(&bytes);
        assert_eq!(records.len(), 2, "version event, image event");
        let event = read_fields(&records[1]);
        assert!(matches!(event[1], (2, Field::Varint(4_000))));
        let (5, Field::Bytes(summary)) = &event[2] else {
            panic!("no summary: {event:?}")
        };
        let value = read_fields(summary);
        let (1, Field::Bytes(value)) = &value[0] else {
            panic!("no value")
        };
        let value = read_fields(value);
        assert!(matches!(&value[0], (1, Field::Bytes(t)) if t == b"video/eval"));
        let (4, Field::Bytes(image)) = &value[1] else {
            panic!("no image: {value:?}")
        };
        let image = read_fields(image);
        assert!(matches!(image[0], (1, Field::Varint(240))), "height");
        assert!(matches!(image[1], (2, Field::Varint(320))), "width");
        assert!(matches!(image[2], (3, Field::Varint(3))), "RGB");
        assert!(matches!(&image[3], (4, Field::Bytes(b)) if b == gif));
    }
}
