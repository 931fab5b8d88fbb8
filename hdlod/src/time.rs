//! Times: every time in the API and in scene files may be an ISO 8601 date or
//! a number of seconds since the scene's start. Inside the library a time is
//! always `f64` seconds since the start.

use crate::error::{Error, Result};
use chrono::{DateTime, NaiveDate, NaiveDateTime, Utc};
use serde::{Deserialize, Serialize};

/// A time as written in a file or a request: an ISO 8601 string or seconds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum TimeValue {
    Seconds(f64),
    Iso(String),
}

/// The time span `[start, start + seconds]` of a scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeSpan {
    pub start: DateTime<Utc>,
    pub seconds: f64,
}

impl TimeSpan {
    pub fn end(&self) -> DateTime<Utc> {
        self.date_at(self.seconds)
    }

    /// The date at `t` seconds since the start (millisecond precision).
    pub fn date_at(&self, t: f64) -> DateTime<Utc> {
        self.start + chrono::Duration::milliseconds((t * 1000.0).round() as i64)
    }

    /// Seconds since the start of an absolute date.
    pub fn seconds_of(&self, date: DateTime<Utc>) -> f64 {
        (date - self.start).num_milliseconds() as f64 / 1000.0
    }

    /// Resolves a time value to seconds since the start. Non-finite seconds
    /// and unparsable dates are errors; the caller adds the file or field.
    pub fn resolve(&self, value: &TimeValue) -> Result<f64> {
        match value {
            TimeValue::Seconds(s) if s.is_finite() => Ok(*s),
            TimeValue::Seconds(s) => Err(Error::value(format!("time {s} is not a finite number"))),
            TimeValue::Iso(text) => parse_date(text).map(|d| self.seconds_of(d)),
        }
    }
}

/// Parses an ISO 8601 date: `2015-02-18`, `2015-02-18T08:00:00` (taken as
/// UTC) or with an offset, `2015-02-18T08:00:00+01:00`.
pub fn parse_date(text: &str) -> Result<DateTime<Utc>> {
    if let Ok(d) = DateTime::parse_from_rfc3339(text) {
        return Ok(d.with_timezone(&Utc));
    }
    if let Ok(d) = NaiveDateTime::parse_from_str(text, "%Y-%m-%dT%H:%M:%S%.f") {
        return Ok(d.and_utc());
    }
    if let Ok(d) = NaiveDate::parse_from_str(text, "%Y-%m-%d") {
        return Ok(d.and_hms_opt(0, 0, 0).expect("midnight exists").and_utc());
    }
    Err(Error::value(format!(
        "{} is not an ISO 8601 date (e.g. 2015-02-18 or 2015-02-18T08:00:00Z)",
        crate::input::quote(text)
    )))
}

/// Formats a date as ISO 8601 in UTC with second precision.
pub fn format_date(date: DateTime<Utc>) -> String {
    date.to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolves_iso_and_seconds() {
        let span = TimeSpan {
            start: parse_date("2024-01-01").unwrap(),
            seconds: 86400.0 * 10.0,
        };
        assert_eq!(span.resolve(&TimeValue::Seconds(5.0)).unwrap(), 5.0);
        assert_eq!(
            span.resolve(&TimeValue::Iso("2024-01-02T00:00:00Z".into()))
                .unwrap(),
            86400.0
        );
        assert_eq!(
            span.resolve(&TimeValue::Iso("2024-01-01T01:00:00+01:00".into()))
                .unwrap(),
            0.0
        );
        assert!(span.resolve(&TimeValue::Seconds(f64::NAN)).is_err());
        assert!(span.resolve(&TimeValue::Iso("yesterday".into())).is_err());
        assert_eq!(format_date(span.end()), "2024-01-11T00:00:00Z");
    }
}
