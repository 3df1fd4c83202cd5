//! A run's report as a spreadsheet.

use crate::{
    Lang, POINT_HEADERS, RunReport, SUMMARY_HEADERS, devices, lang, meta_rows_in, numbers, plots,
    signer, summary_in, tr,
};

/// The report as an XLSX workbook: `results` (the summary), `points`, and
/// one sheet per instrument with its plot data.
pub(crate) fn xlsx_in(
    report: &RunReport,
    lang: Lang,
) -> Result<Vec<u8>, rust_xlsxwriter::XlsxError> {
    use rust_xlsxwriter::{Format, Workbook};
    let mut book = Workbook::new();
    let bold = Format::new().set_bold();
    {
        // What a signer signs, one row per instrument, numbers as numbers.
        let sheet = book.add_worksheet().set_name("verdicts")?;
        let heads = [
            "serial",
            "slot",
            "K2 [µg/g²]",
            "K2 U95 [µg/g²]",
            "k2 P [µg/g²]",
            "k2 P U95 [µg/g²]",
            "k2 N [µg/g²]",
            "k2 N U95 [µg/g²]",
            "judged",
            "limit [µg/g²]",
            "rule",
            "outcome",
            "reason",
        ];
        let widths = [
            12.0, 6.0, 11.0, 13.0, 11.0, 14.0, 11.0, 14.0, 9.0, 12.0, 10.0, 12.0, 80.0,
        ];
        for (c, (head, width)) in heads.iter().zip(widths).enumerate() {
            sheet.write_string_with_format(0, c as u16, lang::header(lang, head), &bold)?;
            sheet.set_column_width(c as u16, width)?;
        }
        let rows = signer::verdict_rows(report, lang);
        for (r, (u, row)) in (1u32..).zip(report.units.iter().zip(&rows)) {
            let f = spinbench_store::ResultFigures::of(u.record());
            sheet.write_string(r, 0, &row.serial)?;
            sheet.write_number(r, 1, row.slot as f64)?;
            for (c, v) in (2u16..).zip([
                f.instrument_k2,
                f.instrument_k2_u95,
                f.k2_p,
                f.k2_p_u95,
                f.k2_n,
                f.k2_n_u95,
            ]) {
                if let Some(v) = v {
                    sheet.write_number(r, c, v)?;
                }
            }
            let decision = u.record().decision;
            if let Some(d) = decision {
                sheet.write_string(r, 8, d.measurand.name())?;
                sheet.write_number(r, 9, d.limit_ug_per_g2)?;
                sheet.write_string(r, 10, lang::decision_rule_name(lang, d.rule))?;
            }
            sheet.write_string(r, 11, &row.verdict)?;
            sheet.write_string(r, 12, &row.reason)?;
        }
    }
    {
        let sheet = book.add_worksheet().set_name("results")?;
        for (c, head) in SUMMARY_HEADERS.iter().enumerate() {
            sheet.write_string_with_format(0, c as u16, lang::header(lang, head), &bold)?;
            let width = match *head {
                "reasons" => 80.0,
                "serial" | "outcome" => 12.0,
                _ => 13.0,
            };
            sheet.set_column_width(c as u16, width)?;
        }
        for (i, row) in summary_in(report, lang).iter().enumerate() {
            let r = (i + 1) as u32;
            sheet.write_string(r, 0, &row.serial)?;
            sheet.write_number(r, 1, row.slot as f64)?;
            sheet.write_string(r, 2, &row.mount)?;
            for (k, v) in numbers(row).iter().enumerate() {
                if let Some(v) = v {
                    sheet.write_number(r, 3 + k as u16, *v)?;
                }
            }
            sheet.write_string(r, 14, lang::outcome(lang, &row.outcome))?;
            sheet.write_string(r, 15, &row.reasons)?;
        }
    }
    // The point table's columns, after the serial number.
    let point_headers: Vec<&str> = std::iter::once("serial").chain(POINT_HEADERS).collect();
    {
        let sheet = book.add_worksheet().set_name("points")?;
        for (c, head) in point_headers.iter().enumerate() {
            sheet.write_string_with_format(0, c as u16, lang::header(lang, head), &bold)?;
            sheet.set_column_width(c as u16, 12.0)?;
        }
        let mut r = 1u32;
        for u in &report.units {
            for p in &u.points {
                sheet.write_string(r, 0, &u.result.serial)?;
                sheet.write_number(r, 1, p.step as f64)?;
                sheet.write_string(r, 2, p.mount.to_string())?;
                sheet.write_number(r, 3, p.g_nominal)?;
                sheet.write_string(
                    r,
                    4,
                    lang::tr_or(
                        lang,
                        &format!("arg.direction.{}", p.direction.as_str()),
                        p.direction.as_str(),
                    ),
                )?;
                sheet.write_number(r, 5, p.g_applied)?;
                sheet.write_number(r, 6, p.rate_deg_s)?;
                sheet.write_number(r, 7, p.output_hz)?;
                sheet.write_number(r, 8, p.std_hz)?;
                sheet.write_number(r, 9, p.n as f64)?;
                if let Some(t) = p.temperature_c {
                    sheet.write_number(r, 10, t)?;
                }
                r += 1;
            }
        }
    }
    {
        // The run's header block, as the PDF and HTML covers give it.
        let sheet = book.add_worksheet().set_name("run")?;
        sheet.set_column_width(0, 22.0)?;
        sheet.set_column_width(1, 60.0)?;
        sheet.set_column_width(2, 50.0)?;
        sheet.write_string(0, 0, tr(lang, "meta.id"))?;
        sheet.write_string(0, 1, &report.run.id)?;
        let meta = meta_rows_in(report, lang);
        for (r, (label, value)) in meta.iter().enumerate() {
            sheet.write_string_with_format(
                r as u32 + 1,
                0,
                tr(lang, &format!("meta.{label}")),
                &bold,
            )?;
            sheet.write_string(r as u32 + 1, 1, value)?;
        }
        // The station's devices with their calibration.
        let mut r = meta.len() as u32 + 2;
        for (c, head) in ["report.device", "report.identity", "report.calibration"]
            .iter()
            .enumerate()
        {
            sheet.write_string_with_format(r, c as u16, tr(lang, head), &bold)?;
        }
        for (role, identity, calibration) in devices(report, lang).unwrap_or_default() {
            r += 1;
            sheet.write_string(r, 0, &role)?;
            sheet.write_string(r, 1, &identity)?;
            sheet.write_string(r, 2, &calibration)?;
        }
    }
    for u in &report.units {
        // Sheet names: at most 31 characters, none of []:*?/\ .
        let name: String = format!("{} s{}", u.result.serial, u.result.slot + 1)
            .chars()
            .map(|c| if "[]:*?/\\".contains(c) { '_' } else { c })
            .take(31)
            .collect();
        let sheet = book.add_worksheet().set_name(&name)?;
        let heads = [
            "mount",
            "level [g]",
            "input [g]",
            "direction",
            "output [Hz]",
            "residual [µg]",
        ];
        for (c, head) in heads.iter().enumerate() {
            sheet.write_string_with_format(0, c as u16, lang::header(lang, head), &bold)?;
            sheet.set_column_width(c as u16, 13.0)?;
        }
        for (r, res) in (1u32..).zip(plots::residuals(u)) {
            sheet.write_string(r, 0, res.mount.to_string())?;
            sheet.write_number(r, 1, res.g_nominal)?;
            sheet.write_number(r, 2, res.g_input)?;
            sheet.write_string(
                r,
                3,
                res.direction.map_or(String::new(), |d| {
                    lang::tr_or(lang, &format!("arg.direction.{}", d.as_str()), d.as_str())
                }),
            )?;
            sheet.write_number(r, 4, res.output)?;
            sheet.write_number(r, 5, res.residual_ug)?;
        }
    }
    book.save_to_buffer()
}
