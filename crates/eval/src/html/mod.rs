//! Self-contained static HTML reports: a page (`index.html`, inline CSS, no
//! scripts, no external links) with its images and plots beside it.
//!
//! - [`calibration_report`], [`write_calibration_html`]: a camera and a
//!   laser against a calibration session: the numbers, Table 1, the
//!   residual and accuracy plots, and per view the image with the detected
//!   corners and the stripe drawn over it, bad views flagged with the reason;
//! - [`write_scan_html`]: a localization with its frames: the result, the
//!   candidates, and per frame a crop around the fruit with the search
//!   region, the stripe, the fruit points, the candidate and the fitted
//!   sphere's silhouette.
//!
//! Images are JPEG, downscaled so that a page stays light.

mod calibration;
mod draw;
mod page;
mod scan;

pub use calibration::{
    CalibrationReport, CalibrationReportView, calibration_report, calibration_report_from_views,
    write_calibration_html,
};
pub use page::escape;
pub use scan::{ScanReport, ScanReportFrame, sphere_silhouette_px, write_scan_html};
