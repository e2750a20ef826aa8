//! The fixed-point controller as a C header for the C firmware (`firmware/`): the sections and
//! delay taps `fracid drive loop` downloads (LOAD_CTRL, LOAD_SECTION), as constants and a loader
//! into `fracfw.h`'s `fw_ctrl`, so a firmware can run the controller without the download.

use crate::ctrl::FixedCtrl;
use crate::protocol::{Configure, MAX_SECTIONS_TAPS, MAX_TAPS};
use std::fmt::Write as _;

/// A 32-bit constant as C99 writes it (`INT32_MIN` cannot be a negated literal).
fn c_i32(v: i32) -> String {
    if v == i32::MIN {
        "(-2147483647 - 1)".into()
    } else {
        v.to_string()
    }
}

/// One `static const int32_t NAME[LEN + 1]` array (one more than its entries, so that it is never
/// empty in C).
fn c_array(o: &mut String, name: &str, len_macro: &str, values: &[i32]) {
    let mut body: Vec<String> = values.iter().map(|&v| c_i32(v)).collect();
    body.push("0".into());
    let _ = writeln!(o, "static const int32_t {name}[{len_macro} + 1u] = {{");
    for chunk in body.chunks(6) {
        let _ = writeln!(o, "    {},", chunk.join(", "));
    }
    let _ = writeln!(o, "}};");
}

impl FixedCtrl {
    /// The controller as a C99 header for the firmware: its format, sections (`a_q30`, `g_q24`),
    /// delay taps (`h_q24`), feed-through (`d_q24`, `dinv_q16`), the sample period `dt` and the
    /// channel scales of `conf` it was converted for, and `fracid_ctrl_load(fw_ctrl *)`, which
    /// fills the firmware's controller as LOAD_CTRL and LOAD_SECTION do and zeroes its states.
    /// `about` (the controller's text) goes into the header's comment.
    pub fn c_header(&self, about: &str, dt: f64, conf: &Configure) -> String {
        let about = about.replace("*/", "* /");
        let mut o = String::new();
        let _ = writeln!(
            o,
            "/* The speed controller C(s) = {about}\n * realised every {dt} s as fixed-point \
             parallel first-order sections (PROTOCOL.md section 3, \"Speed loop\"): what\n * \
             `fracid drive loop` downloads, written by `fracid export --format c`. Channel \
             scales:\n * {} uV and {} urad/s per LSB. Include after fracfw.h. */",
            conf.scale_u_uv, conf.scale_y_urad_s
        );
        let _ = writeln!(o, "#ifndef FRACID_CTRL_H\n#define FRACID_CTRL_H\n");
        let _ = writeln!(o, "#include \"fracfw.h\"\n");
        let defs = [
            ("FRACID_CTRL_FORMAT", format!("{}u", self.format())),
            (
                "FRACID_CTRL_SAMPLE_RATE_HZ",
                format!("{}u", conf.sample_rate_hz),
            ),
            ("FRACID_CTRL_SCALE_U_UV", format!("{}u", conf.scale_u_uv)),
            (
                "FRACID_CTRL_SCALE_Y_URAD_S",
                format!("{}u", conf.scale_y_urad_s),
            ),
            (
                "FRACID_CTRL_N_SECTIONS",
                format!("{}u", self.sections.len()),
            ),
            ("FRACID_CTRL_N_TAPS", format!("{}u", self.taps.len())),
            ("FRACID_CTRL_D_Q24", format!("({})", c_i32(self.d_q24))),
            (
                "FRACID_CTRL_DINV_Q16",
                format!("({})", c_i32(self.dinv_q16)),
            ),
        ];
        for (k, v) in defs {
            let _ = writeln!(o, "#define {k} {v}");
        }
        let _ = writeln!(
            o,
            "\n#if FRACID_CTRL_N_SECTIONS > FW_MAX_SECTIONS || FRACID_CTRL_N_TAPS > FW_MAX_TAPS\n\
             #error \"this controller needs more sections or taps than the firmware holds\"\n#endif\n"
        );
        debug_assert!(self.sections.len() <= MAX_SECTIONS_TAPS as usize);
        debug_assert!(self.taps.len() <= MAX_TAPS as usize);
        let a: Vec<i32> = self.sections.iter().map(|s| s.a_q30).collect();
        let g: Vec<i32> = self.sections.iter().map(|s| s.g_q24).collect();
        c_array(&mut o, "fracid_ctrl_a_q30", "FRACID_CTRL_N_SECTIONS", &a);
        c_array(&mut o, "fracid_ctrl_g_q24", "FRACID_CTRL_N_SECTIONS", &g);
        c_array(
            &mut o,
            "fracid_ctrl_h_q24",
            "FRACID_CTRL_N_TAPS",
            &self.taps,
        );
        // the loops only over what there is (a loop to 0 is a warning in C)
        let sections = if self.sections.is_empty() {
            String::new()
        } else {
            "    for (i = 0; i < FRACID_CTRL_N_SECTIONS; i++) {\n        c->a_q30[i] = \
             fracid_ctrl_a_q30[i];\n        c->g_q24[i] = fracid_ctrl_g_q24[i];\n    }\n"
                .to_string()
        };
        let taps = if self.taps.is_empty() {
            String::new()
        } else {
            "    for (i = 0; i < FRACID_CTRL_N_TAPS; i++) {\n        c->h_q24[i] = \
             fracid_ctrl_h_q24[i];\n    }\n"
                .to_string()
        };
        let index = if sections.is_empty() && taps.is_empty() {
            ""
        } else {
            "    uint16_t i;\n"
        };
        let _ = write!(
            o,
            "
/** Load the controller into the firmware's (as LOAD_CTRL and LOAD_SECTION do), its states
 * zeroed. */
static inline void fracid_ctrl_load(fw_ctrl *c)
{{
{index}    c->d_q24 = FRACID_CTRL_D_Q24;
    c->dinv_q16 = FRACID_CTRL_DINV_Q16;
    c->n = (uint16_t)FRACID_CTRL_N_SECTIONS;
    c->n_taps = (uint16_t)FRACID_CTRL_N_TAPS;
    c->loaded = (uint16_t)(FRACID_CTRL_N_SECTIONS + FRACID_CTRL_N_TAPS);
{sections}{taps}    fw_ctrl_reset(c);
}}

#endif /* FRACID_CTRL_H */
"
        );
        o
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ctrl::Section;

    #[test]
    fn the_header_holds_every_coefficient_and_the_loader() {
        let k = FixedCtrl {
            d_q24: 1 << 20,
            dinv_q16: 1 << 20,
            sections: vec![
                Section {
                    a_q30: 1 << 30,
                    g_q24: 12_345,
                },
                Section {
                    a_q30: -7,
                    g_q24: i32::MIN,
                },
            ],
            taps: vec![99],
        };
        let h = k.c_header("kp + ki/s^0.9", 1e-3, &Configure::default());
        assert!(h.contains("#define FRACID_CTRL_N_SECTIONS 2u"));
        assert!(h.contains("#define FRACID_CTRL_N_TAPS 1u"));
        assert!(h.contains("#define FRACID_CTRL_FORMAT 2u"));
        assert!(h.contains("#define FRACID_CTRL_D_Q24 (1048576)"));
        assert!(h.contains("1073741824, -7, 0,"));
        assert!(h.contains("12345, (-2147483647 - 1), 0,"));
        assert!(h.contains("99, 0,"));
        assert!(h.contains("static inline void fracid_ctrl_load(fw_ctrl *c)"));
    }
}
