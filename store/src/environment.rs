//! The air around a survey's tracker measurements, as stored with each
//! (`raw_readings.air_*`, migration 9): its ranges over the survey, and the
//! temperature against time. A store of an older schema read as it is has
//! none.

use super::{Store, on_pool};
use serde::Serialize;
use sqlx::Row;

/// The least, greatest and mean of one quantity over a survey.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Range {
    pub min: f64,
    pub max: f64,
    pub mean: f64,
}

/// The air over a survey's measurements, each quantity's range.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Measured {
    /// How many measurements reported it.
    pub count: i64,
    pub temperature_c: Range,
    pub pressure_hpa: Range,
    pub humidity_pct: Range,
}

impl Store {
    /// The ranges of the air the survey `id`'s measurements reported, or
    /// `None` when none did. Computed here in seq order from the values
    /// (not by the database's aggregates), so both stores give the same bits.
    pub async fn environment(&self, id: i64) -> anyhow::Result<Option<Measured>> {
        if !self.environment {
            return Ok(None);
        }
        let rows: Vec<[f64; 3]> = on_pool!(self, |pool| {
            sqlx::query(
                "SELECT air_temperature_c AS t, air_pressure_hpa AS p, air_humidity_pct AS h FROM raw_readings \
                 WHERE survey_id = $1 AND air_temperature_c IS NOT NULL ORDER BY seq",
            )
            .bind(id)
            .fetch_all(pool)
            .await?
            .iter()
            .map(|r| -> anyhow::Result<[f64; 3]> { Ok([r.try_get("t")?, r.try_get("p")?, r.try_get("h")?]) })
            .collect::<anyhow::Result<_>>()?
        });
        if rows.is_empty() {
            return Ok(None);
        }
        let range = |i: usize| {
            let (min, max, sum) = rows
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY, 0.0), |(lo, hi, s), r| (lo.min(r[i]), hi.max(r[i]), s + r[i]));
            Range { min, max, mean: sum / rows.len() as f64 }
        };
        Ok(Some(Measured {
            count: rows.len() as i64,
            temperature_c: range(0),
            pressure_hpa: range(1),
            humidity_pct: range(2),
        }))
    }

    /// The air temperature of the survey `id`'s measurements against the
    /// time of their samples, `(s, °C)`, in seq order (those with a time).
    pub async fn temperature_series(&self, id: i64) -> anyhow::Result<Vec<(f64, f64)>> {
        if !self.environment {
            return Ok(Vec::new());
        }
        on_pool!(self, |pool| {
            sqlx::query(
                "SELECT s.timestamp_s AS t, r.air_temperature_c AS c FROM samples AS s JOIN raw_readings AS r \
                 ON r.survey_id = s.survey_id AND r.seq = s.seq WHERE s.survey_id = $1 \
                 AND r.air_temperature_c IS NOT NULL AND s.timestamp_s IS NOT NULL ORDER BY s.seq",
            )
            .bind(id)
            .fetch_all(pool)
            .await?
            .iter()
            .map(|r| Ok((r.try_get("t")?, r.try_get("c")?)))
            .collect()
        })
    }
}
