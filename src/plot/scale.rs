//! The colour scale of a map picture: linear or logarithmic, over the data or a given range, with colour-bar
//! ticks that include both ends (a reader must see what the darkest and the brightest colour mean).

use anyhow::{bail, Result};

use super::svg::{viridis, Axis};

/// How values map to colours.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Scale {
    /// Evenly in the value.
    #[default]
    Linear,
    /// Evenly in the value's logarithm (compliances spanning decades); needs positive values.
    Log,
}

/// A value range mapped onto the colour map; values outside it take the end colours.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ColourScale {
    /// The value of the first colour.
    pub lo: f64,
    /// The value of the last colour.
    pub hi: f64,
    /// Linear or logarithmic.
    pub scale: Scale,
}

impl ColourScale {
    /// The scale over `values` (finite ones) or over `range` where given. A log scale refuses a range or
    /// data that is not positive, saying what to do.
    pub fn new(values: &[f64], scale: Scale, range: Option<(f64, f64)>, what: &str) -> Result<ColourScale> {
        let (mut lo, mut hi) = match range {
            Some((lo, hi)) => {
                if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                    bail!("the colour range {lo},{hi} must be two finite numbers MIN < MAX");
                }
                (lo, hi)
            }
            None => values
                .iter()
                .filter(|v| v.is_finite())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v))),
        };
        if scale == Scale::Log {
            let positive: Vec<f64> = values.iter().copied().filter(|v| v.is_finite() && *v > 0.0).collect();
            if range.is_none() && positive.len() < values.iter().filter(|v| v.is_finite()).count() {
                bail!("a log colour scale needs positive values, and {what} has values <= 0: use --scale linear");
            }
            if lo <= 0.0 {
                bail!("a log colour scale needs a positive range, not {lo}..{hi}: use --scale linear");
            }
        }
        if !lo.is_finite() {
            // Nothing to colour: any scale will do; the picture says there is no value.
            (lo, hi) = (0.0, 1.0);
        } else if hi <= lo {
            // One value: a scale around it, so that it takes the middle colour.
            let pad = if lo == 0.0 { 1.0 } else { 0.5 * lo.abs() };
            (lo, hi) = match scale {
                Scale::Linear => (lo - pad, hi + pad),
                Scale::Log => (lo / 2.0, hi * 2.0),
            };
        }
        Ok(ColourScale { lo, hi, scale })
    }

    /// Where a value lies on the scale, 0 at `lo` and 1 at `hi`, clamped.
    pub fn fraction(&self, v: f64) -> f64 {
        let f = match self.scale {
            Scale::Linear => (v - self.lo) / (self.hi - self.lo),
            Scale::Log => (v.ln() - self.lo.ln()) / (self.hi.ln() - self.lo.ln()),
        };
        if f.is_finite() {
            f.clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// The colour of a value.
    pub fn colour(&self, v: f64) -> String {
        viridis(self.fraction(v))
    }

    /// The values labelled on the colour bar: both ends, and round values between them that do not crowd
    /// the ends (within 9% of the bar: 18 px of a 200 px bar, for 10 px text).
    pub fn ticks(&self) -> Vec<f64> {
        let inner: Vec<f64> = match self.scale {
            Scale::Linear => Axis { lo: self.lo, hi: self.hi, from: 0.0, to: 1.0 }.ticks(),
            Scale::Log => {
                let (a, b) = (self.lo.log10().ceil() as i32, self.hi.log10().floor() as i32);
                let every = ((b - a) / 5 + 1).max(1);
                (a..=b).filter(|e| (e - a) % every == 0).map(|e| 10f64.powi(e)).collect()
            }
        };
        let mut ticks = vec![self.lo];
        ticks.extend(inner.into_iter().filter(|t| {
            let f = self.fraction(*t);
            f > 0.09 && f < 0.91
        }));
        ticks.push(self.hi);
        ticks
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The colour bar names its two ends whatever the data; a log scale spaces decades evenly and refuses
    /// values it cannot place.
    #[test]
    fn colour_bar_ticks_include_both_ends() {
        let s = ColourScale::new(&[0.013, 0.02, 0.047], Scale::Linear, None, "c").unwrap();
        let t = s.ticks();
        assert_eq!((t[0], *t.last().unwrap()), (0.013, 0.047));
        assert!(t.windows(2).all(|w| w[0] < w[1]), "{t:?}");
        let log = ColourScale::new(&[1e-4, 3e-2], Scale::Log, None, "c").unwrap();
        assert!((log.fraction(1e-3) - (1.0f64 / 2.477_121_254_719_662)).abs() < 1e-12);
        assert_eq!(log.ticks()[0], 1e-4);
        assert!(log.ticks().contains(&1e-3) && log.ticks().contains(&1e-2));
        assert!(ColourScale::new(&[-1.0, 2.0], Scale::Log, None, "dx_mm").is_err());
        let fixed = ColourScale::new(&[5.0], Scale::Linear, Some((0.0, 10.0)), "c").unwrap();
        assert_eq!(fixed.fraction(5.0), 0.5);
        assert_eq!(fixed.fraction(20.0), 1.0);
    }
}
