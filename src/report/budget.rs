//! Budgets: the runs of a sweep, as `aobake report --budgets` writes them.
//!
//! In: a list such as `mc:64,sheared:8:4,adaptive:64`. Out: [`Budget`]s, each a
//! method and its options, and the [`BakeSettings`] a run bakes with.

use crate::bake::adaptive::{AdaptiveOptions, MAX_ADAPTIVE_RAYS};
use crate::bake::sheared::{MAX_FILTER_RAYS, ShearedOptions};
use crate::error::{Error, Result};
use crate::job::settings::{BakeSettings, DEFAULT_RAYS, Method};

/// The sweep used when `--budgets` is not given.
pub const DEFAULT_BUDGETS: &str = "mc:8,mc:16,mc:32,mc:64,mc:128,mc:256,mc:512,\
sheared:8:4,sheared:16:4,sheared:16:8,adaptive:16,adaptive:32,adaptive:64,adaptive:128";

/// Monte Carlo rays whose error is the equal-error target (the `--rays`
/// default).
pub const TARGET_RAYS: u32 = DEFAULT_RAYS;

/// One run of the sweep: a method and its budget.
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    pub method: Method,
    /// Monte Carlo rays per texel (Monte Carlo only).
    pub rays: u32,
    pub sheared: ShearedOptions,
    pub adaptive: AdaptiveOptions,
}

impl Budget {
    /// `mc:N`, `adaptive:QUALITY[:PRE[:MAX]]` (the Monte Carlo ray count
    /// whose error it aims at, pre-pass rays, most rays per texel),
    /// `adaptive-mean:MEAN[:PRE[:MAX]]` (a fixed mean rays per texel) or `sheared:K:R[:C[:O[:W]]]` (`filtered:` too; sparse rays, gather radius,
    /// rays per brute-forced cell, Omega_v, min weight).
    pub fn label(&self) -> String {
        match self.method {
            Method::Mc => format!("mc:{}", self.rays),
            Method::Sheared => {
                let f = &self.sheared;
                let d = ShearedOptions::default();
                let mut s = format!("sheared:{}:{}", f.sparse_rays, f.gather_radius);
                if (f.cell_rays, f.omega_v_max, f.min_weight)
                    != (d.cell_rays, d.omega_v_max, d.min_weight)
                {
                    s += &format!(":{}:{}:{}", f.cell_rays, f.omega_v_max, f.min_weight);
                }
                s
            }
            Method::Adaptive => {
                let a = &self.adaptive;
                let d = AdaptiveOptions::default();
                let mut s = if a.mean_rays > 0 {
                    format!("adaptive-mean:{}", a.mean_rays)
                } else {
                    format!("adaptive:{}", a.quality)
                };
                if (a.pre_rays, a.max_rays) != (d.pre_rays, d.max_rays) {
                    s += &format!(":{}:{}", a.pre_rays, a.max_rays);
                }
                s
            }
        }
    }

    pub fn is_default(&self) -> bool {
        match self.method {
            Method::Mc => self.rays == TARGET_RAYS,
            Method::Sheared => self.sheared == ShearedOptions::default(),
            Method::Adaptive => self.adaptive == AdaptiveOptions::default(),
        }
    }
}

impl Budget {
    /// Monte Carlo with `rays` rays per texel.
    pub fn mc(rays: u32) -> Budget {
        Budget {
            method: Method::Mc,
            rays,
            sheared: ShearedOptions::default(),
            adaptive: AdaptiveOptions::default(),
        }
    }

    /// The sheared method with its default options.
    pub fn sheared_default() -> Budget {
        Budget {
            method: Method::Sheared,
            rays: 0,
            sheared: ShearedOptions::default(),
            adaptive: AdaptiveOptions::default(),
        }
    }

    /// The adaptive method with its default options.
    pub fn adaptive_default() -> Budget {
        Budget {
            method: Method::Adaptive,
            rays: 0,
            sheared: ShearedOptions::default(),
            adaptive: AdaptiveOptions::default(),
        }
    }

    /// `base` with this budget's method and options, and `seed`.
    pub fn settings(&self, base: &BakeSettings, seed: u64) -> BakeSettings {
        BakeSettings {
            method: self.method,
            // Other methods do not read it; the base's passes validation.
            rays: if self.method == Method::Mc {
                self.rays
            } else {
                base.rays
            },
            sheared: self.sheared,
            adaptive: self.adaptive,
            seed,
            ..base.clone()
        }
    }
}

/// Parses a comma-separated budget list (see [`Budget::label`]).
pub fn parse_budgets(text: &str) -> Result<Vec<Budget>> {
    let bad = |item: &str, why: &str| Error::option_item("budgets", item, why);
    let mut out = Vec::new();
    for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let parts: Vec<&str> = item.split(':').collect();
        let num = |i: usize| -> Result<Option<f64>> {
            match parts.get(i) {
                None => Ok(None),
                Some(p) => match p.parse::<f64>() {
                    Ok(v) if v.is_finite() && v > 0.0 => Ok(Some(v)),
                    _ => Err(bad(item, "numbers must be finite and > 0")),
                },
            }
        };
        let budget = match parts[0] {
            "mc" => {
                if parts.len() != 2 {
                    return Err(bad(item, "expected mc:RAYS"));
                }
                let rays = num(1)?.unwrap_or(0.0);
                if rays.fract() != 0.0 || rays > 1e6 {
                    return Err(bad(item, "rays must be a whole number up to 1000000"));
                }
                Budget::mc(rays as u32)
            }
            "sheared" | "filtered" => {
                if parts.len() > 6 {
                    return Err(bad(item, "expected sheared:K:R[:C[:O[:W]]]"));
                }
                let mut f = ShearedOptions::default();
                if let Some(k) = num(1)? {
                    if k.fract() != 0.0 || k > MAX_FILTER_RAYS as f64 {
                        return Err(bad(
                            item,
                            &format!("sparse rays must be a whole number up to {MAX_FILTER_RAYS}"),
                        ));
                    }
                    f.sparse_rays = k as u32;
                }
                if let Some(r) = num(2)? {
                    f.gather_radius = r as f32;
                }
                if let Some(c) = num(3)? {
                    if c.fract() != 0.0 || c > MAX_FILTER_RAYS as f64 {
                        return Err(bad(
                            item,
                            &format!("cell rays must be a whole number up to {MAX_FILTER_RAYS}"),
                        ));
                    }
                    f.cell_rays = c as u32;
                }
                if let Some(o) = num(4)? {
                    f.omega_v_max = o as f32;
                }
                if let Some(w) = num(5)? {
                    f.min_weight = w as f32;
                }
                Budget {
                    method: Method::Sheared,
                    rays: 0,
                    sheared: f,
                    adaptive: AdaptiveOptions::default(),
                }
            }
            "adaptive" | "adaptive-mean" => {
                if parts.len() > 4 {
                    return Err(bad(
                        item,
                        "expected adaptive:QUALITY[:PRE[:MAX]] or adaptive-mean:MEAN[:PRE[:MAX]]",
                    ));
                }
                let whole = |i: usize| -> Result<Option<u32>> {
                    match num(i)? {
                        Some(v) if v.fract() == 0.0 && v <= MAX_ADAPTIVE_RAYS as f64 => {
                            Ok(Some(v as u32))
                        }
                        Some(_) => Err(bad(
                            item,
                            &format!("ray counts must be whole numbers up to {MAX_ADAPTIVE_RAYS}"),
                        )),
                        None => Ok(None),
                    }
                };
                let mut a = AdaptiveOptions::default();
                if let Some(m) = whole(1)? {
                    if parts[0] == "adaptive" {
                        a.quality = m;
                    } else {
                        a.mean_rays = m;
                    }
                }
                if let Some(p) = whole(2)? {
                    a.pre_rays = p;
                }
                if let Some(m) = whole(3)? {
                    a.max_rays = m;
                }
                Budget {
                    method: Method::Adaptive,
                    rays: 0,
                    sheared: ShearedOptions::default(),
                    adaptive: a,
                }
            }
            other => {
                return Err(bad(
                    item,
                    &format!("unknown method '{other}' (mc, sheared, adaptive or adaptive-mean)"),
                ));
            }
        };
        out.push(budget);
    }
    if out.is_empty() {
        return Err(Error::option("budgets", "is empty"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budgets_parse_and_refuse() {
        let b = parse_budgets("mc:8, filtered:16:6, filtered:8:4:3:1.5:2").unwrap();
        assert_eq!(b.len(), 3);
        assert_eq!((b[0].method, b[0].rays), (Method::Mc, 8));
        assert_eq!(b[1].sheared.sparse_rays, 16);
        assert_eq!(b[1].sheared.gather_radius, 6.0);
        assert_eq!(b[2].sheared.cell_rays, 3);
        assert_eq!(b[2].sheared.omega_v_max, 1.5);
        assert_eq!(b[2].sheared.min_weight, 2.0);
        assert_eq!(b[0].label(), "mc:8");
        assert_eq!(b[1].label(), "sheared:16:6");
        assert_eq!(b[2].label(), "sheared:8:4:3:1.5:2");
        for bad in [
            "",
            "mc",
            "mc:0",
            "mc:-4",
            "mc:1.5",
            "mc:nan",
            "pt:4",
            "filtered:a",
            "mc:8:9",
        ] {
            assert!(parse_budgets(bad).is_err(), "{bad}");
        }
        assert!(parse_budgets(DEFAULT_BUDGETS).unwrap().len() >= 10);
    }
}
