//! The host side of the drive's scope (`firmware::scope`, objects 0x2500-0x2510):
//! channel names from the product dictionary, the configuration written over SDO
//! (ethercrab), the record read back block by block, and its CSV and PNG.
//!
//! Used by the `scope` program (`tests-host/src/bin/scope.rs`) and its real-socket
//! test (`tests-host/tests/scope_veth.rs`).

use ecat_slave_stack::od;
use ethercrab::error::Error;
use ethercrab::SubDeviceRef;
use firmware::scope::{self, command};
use plotters::prelude::*;
use std::ops::Deref;
use std::path::Path;

/// One channel: an entry of the dictionary.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Channel {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Bit length of the entry.
    pub bits: u8,
    /// Entry name (object name for a VAR), for the CSV header and the plot.
    pub name: String,
    /// Unit text ("inc", "mA", …), empty when dimensionless.
    pub unit: String,
}

impl Channel {
    /// Parses `INDEX[:SUB]` (hex with `0x`, or decimal): the entry's length, name and
    /// unit come from the product dictionary; it must be PDO-mappable and at most 32
    /// bits, as the drive checks.
    pub fn parse(text: &str) -> Result<Channel, String> {
        let mut parts = text.split(':');
        let index = parse_u32(parts.next().unwrap_or(""))
            .and_then(|v| u16::try_from(v).ok())
            .ok_or_else(|| format!("channel '{text}': INDEX[:SUB], e.g. 0x6064 or 0x2510:3"))?;
        let sub = match parts.next() {
            Some(s) => parse_u32(s)
                .and_then(|v| u8::try_from(v).ok())
                .ok_or_else(|| format!("channel '{text}': bad sub-index"))?,
            None => 0,
        };
        let objects = firmware::dictionary::OBJECTS;
        let obj = od::find(objects, index)
            .ok_or_else(|| format!("channel '{text}': no object {index:#06x}"))?;
        let e = obj
            .entry(sub)
            .ok_or_else(|| format!("channel '{text}': no sub-index {sub}"))?;
        if e.pdo_mappable() == od::PdoMappable::No || e.bits() == 0 || e.bits() > 32 {
            return Err(format!(
                "channel '{text}': {} is not a PDO-mappable entry of at most 32 bits",
                e.name()
            ));
        }
        let name = if obj.code() == od::ObjectCode::Var {
            obj.name().to_string()
        } else {
            format!("{} {}", obj.name(), e.name())
        };
        Ok(Channel {
            index,
            sub,
            bits: e.bits() as u8,
            name,
            unit: e.unit_text().to_string(),
        })
    }

    /// The 0x2501 value: `index << 16 | sub << 8 | bits`.
    pub fn mapping(&self) -> u32 {
        od::ObjectKey::new(self.index, self.sub).mapping_word(self.bits)
    }

    /// CSV column / legend: `0x6064 Position actual value [inc]`.
    pub fn label(&self) -> String {
        let key = if self.sub == 0 {
            format!("{:#06x}", self.index)
        } else {
            format!("{:#06x}:{}", self.index, self.sub)
        };
        if self.unit.is_empty() {
            format!("{key} {}", self.name)
        } else {
            format!("{key} {} [{}]", self.name, self.unit)
        }
    }
}

fn parse_u32(s: &str) -> Option<u32> {
    let s = s.trim();
    match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(h) => u32::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

/// Trigger conditions (0x2500:04) by name.
pub const CONDITIONS: [(&str, u8); 6] = [
    ("immediate", 0),
    ("rising", 1),
    ("falling", 2),
    ("either", 3),
    ("above", 4),
    ("below", 5),
];

/// What to record and when.
#[derive(Debug, Clone, PartialEq)]
pub struct ScopeConfig {
    /// Channels, 1 to 8.
    pub channels: Vec<Channel>,
    /// One sample every `divisor` periods of the time base.
    pub divisor: u16,
    /// Time base: the servo period (100 µs; the internal signals 0x2510 at that
    /// rate) instead of the supervision tick (1 ms).
    pub servo_rate: bool,
    /// Trigger channel, 1-based.
    pub trigger_channel: u8,
    /// Trigger level, in the trigger channel's units.
    pub level: i32,
    /// 0x2500:04 ([`CONDITIONS`]).
    pub condition: u8,
    /// Samples kept before the trigger.
    pub pretrigger: u16,
    /// Normal mode (re-arms after the record was read) instead of single.
    pub normal: bool,
}

impl ScopeConfig {
    /// Period of the time base, ms.
    pub fn period_ms(&self) -> f64 {
        if self.servo_rate {
            f64::from(firmware::motion::SERVO_TS) * 1e3
        } else {
            firmware::drive::TICK_US as f64 * 1e-3
        }
    }

    /// Samples per channel the drive's buffer holds with these channels.
    pub fn depth(&self) -> usize {
        scope::BUFFER_WORDS / self.channels.len().max(1)
    }
}

/// Writes the configuration (stops the scope first; the channel list in the PDO
/// mapping edit order: count 0, entries, count).
pub async fn configure<S>(sd: &SubDeviceRef<'_, S>, cfg: &ScopeConfig) -> Result<(), Error>
where
    S: Deref<Target = ethercrab::SubDevice>,
{
    sd.sdo_write(scope::CONFIG, 7, command::STOP).await?;
    sd.sdo_write(scope::CHANNEL_LIST, 0, 0u8).await?;
    for (k, ch) in cfg.channels.iter().enumerate() {
        sd.sdo_write(scope::CHANNEL_LIST, k as u8 + 1, ch.mapping())
            .await?;
    }
    sd.sdo_write(scope::CHANNEL_LIST, 0, cfg.channels.len() as u8)
        .await?;
    sd.sdo_write(scope::CONFIG, 1, cfg.divisor).await?;
    sd.sdo_write(scope::CONFIG, 2, cfg.trigger_channel).await?;
    sd.sdo_write(scope::CONFIG, 3, cfg.level).await?;
    sd.sdo_write(scope::CONFIG, 4, cfg.condition).await?;
    sd.sdo_write(scope::CONFIG, 5, cfg.pretrigger).await?;
    sd.sdo_write(scope::CONFIG, 6, u8::from(cfg.normal)).await?;
    sd.sdo_write(scope::CONFIG, 8, u8::from(cfg.servo_rate))
        .await?;
    Ok(())
}

/// Writes a command to 0x2500:07 ([`command`]).
pub async fn send_command<S>(sd: &SubDeviceRef<'_, S>, c: u8) -> Result<(), Error>
where
    S: Deref<Target = ethercrab::SubDevice>,
{
    sd.sdo_write(scope::CONFIG, 7, c).await
}

/// 0x2502: state, samples recorded, trigger position, samples per channel, records.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Status {
    /// 0 idle, 1 armed, 2 triggered, 3 done.
    pub state: u8,
    /// Samples per channel in the record.
    pub samples: u16,
    /// Sample number of the trigger.
    pub trigger: u16,
    /// Samples per channel of the buffer.
    pub depth: u16,
    /// Records completed.
    pub records: u16,
}

/// Reads 0x2502.
pub async fn status<S>(sd: &SubDeviceRef<'_, S>) -> Result<Status, Error>
where
    S: Deref<Target = ethercrab::SubDevice>,
{
    Ok(Status {
        state: sd.sdo_read(scope::STATUS, 1).await?,
        samples: sd.sdo_read(scope::STATUS, 2).await?,
        trigger: sd.sdo_read(scope::STATUS, 3).await?,
        depth: sd.sdo_read(scope::STATUS, 4).await?,
        records: sd.sdo_read(scope::STATUS, 5).await?,
    })
}

/// A record read back.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// The channels, in column order.
    pub channels: Vec<Channel>,
    /// Time between two samples, ms.
    pub period_ms: f64,
    /// Sample number of the trigger.
    pub trigger: usize,
    /// One row per sample, oldest first; one value per channel.
    pub rows: Vec<Vec<i32>>,
}

/// Reads the done record (`st`: its status) block by block from 0x2503 (segmented
/// uploads).
pub async fn read_record<S>(
    sd: &SubDeviceRef<'_, S>,
    cfg: &ScopeConfig,
    st: &Status,
) -> Result<Record, Error>
where
    S: Deref<Target = ethercrab::SubDevice>,
{
    let n = cfg.channels.len();
    let total = usize::from(st.samples) * n * 4;
    let mut bytes = Vec::with_capacity(total);
    let mut sub = 1u8;
    while bytes.len() < total {
        let block = sdo_upload(sd, scope::DATA, sub).await?;
        if block.is_empty() {
            return Err(Error::Internal);
        }
        bytes.extend_from_slice(&block);
        sub += 1;
    }
    Ok(Record::from_bytes(cfg, st, &bytes))
}

pub use crate::coe_client::sdo_upload;

impl Record {
    /// The record of `bytes` (0x2503's blocks, concatenated).
    pub fn from_bytes(cfg: &ScopeConfig, st: &Status, bytes: &[u8]) -> Record {
        let n = cfg.channels.len().max(1);
        let words: Vec<i32> = bytes
            .chunks_exact(4)
            .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        Record {
            channels: cfg.channels.clone(),
            period_ms: f64::from(cfg.divisor) * cfg.period_ms(),
            trigger: usize::from(st.trigger),
            rows: words
                .chunks_exact(n)
                .take(usize::from(st.samples))
                .map(<[i32]>::to_vec)
                .collect(),
        }
    }

    /// Time of sample `k` from the trigger, ms.
    pub fn time_ms(&self, k: usize) -> f64 {
        (k as f64 - self.trigger as f64) * self.period_ms
    }

    /// CSV: `sample,time_ms,<channel labels>`, one line per sample, time 0 at the
    /// trigger.
    pub fn csv(&self) -> String {
        let mut out = String::from("sample,time_ms");
        for c in &self.channels {
            out.push(',');
            out.push_str(&c.label().replace(',', ";"));
        }
        out.push('\n');
        for (k, row) in self.rows.iter().enumerate() {
            out.push_str(&format!("{k},{:.3}", self.time_ms(k)));
            for v in row {
                out.push_str(&format!(",{v}"));
            }
            out.push('\n');
        }
        out
    }

    /// A PNG with one panel per channel over time (ms from the trigger), the trigger
    /// marked by a vertical line; `text`: labels (see [`crate::plot::load_font`]).
    pub fn plot(&self, path: &Path, title: &str, text: bool) -> Result<(), String> {
        self.draw(path, title, text).map_err(|e| e.to_string())
    }

    fn draw(&self, path: &Path, title: &str, text: bool) -> Result<(), Box<dyn std::error::Error>> {
        const COLOURS: [RGBColor; 8] = [
            RGBColor(31, 119, 180),
            RGBColor(214, 39, 40),
            RGBColor(44, 160, 44),
            RGBColor(255, 127, 14),
            RGBColor(148, 103, 189),
            RGBColor(140, 86, 75),
            RGBColor(227, 119, 194),
            RGBColor(23, 190, 207),
        ];
        let n = self.channels.len().max(1);
        let root = BitMapBackend::new(path, (1000, 120 + 170 * n as u32)).into_drawing_area();
        root.fill(&WHITE)?;
        let root = if text {
            root.titled(title, ("sans-serif", 22))?
        } else {
            root
        };
        let panels = root.split_evenly((n, 1));
        let x0 = self.time_ms(0);
        let x1 = self
            .time_ms(self.rows.len().saturating_sub(1))
            .max(x0 + 1.0);
        for (c, panel) in panels.iter().enumerate() {
            let pts: Vec<(f64, f64)> = self
                .rows
                .iter()
                .enumerate()
                .map(|(k, r)| (self.time_ms(k), f64::from(r.get(c).copied().unwrap_or(0))))
                .collect();
            let lo = pts.iter().map(|p| p.1).fold(f64::MAX, f64::min);
            let hi = pts.iter().map(|p| p.1).fold(f64::MIN, f64::max);
            let (lo, hi) = if pts.is_empty() { (0.0, 1.0) } else { (lo, hi) };
            let pad = ((hi - lo) * 0.1).max(1.0);
            let mut b = ChartBuilder::on(panel);
            b.margin(8);
            if text {
                let label = self.channels.get(c).map(Channel::label).unwrap_or_default();
                b.caption(label, ("sans-serif", 16))
                    .x_label_area_size(30)
                    .y_label_area_size(70);
            }
            let mut chart = b.build_cartesian_2d(x0..x1, (lo - pad)..(hi + pad))?;
            let mut mesh = chart.configure_mesh();
            if text {
                mesh.x_desc("ms from the trigger");
            } else {
                mesh.x_labels(0).y_labels(0);
            }
            mesh.draw()?;
            let colour = COLOURS[c % COLOURS.len()];
            chart.draw_series(LineSeries::new(pts, colour.stroke_width(2)))?;
            chart.draw_series(LineSeries::new(
                [(0.0, lo - pad), (0.0, hi + pad)],
                BLACK.mix(0.5).stroke_width(1),
            ))?;
        }
        root.present()?;
        Ok(())
    }
}
