//! `alacs session init`: session.yaml for a folder of board images.

use alacs::Session;
use alacs::model::io::write_file;
use alacs::model::{BoardSpec, CharucoMarkers, SESSION_FILE};
use anyhow::anyhow;
use serde_json::json;

use crate::args::SessionInitArgs;
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Runs `alacs session init`.
pub fn init(args: &SessionInitArgs) -> CmdResult {
    let (cols, rows) = args.board;
    let (square_x_mm, square_y_mm) = args.square_mm;
    let mut board = BoardSpec::checkerboard(cols, rows, square_x_mm, square_y_mm);
    if let (Some(dictionary), Some(marker_mm)) = (args.charuco, args.marker_mm) {
        board.markers = Some(CharucoMarkers { marker_mm, dictionary });
    }
    let session = Session::from_image_folder(&args.dir, board, args.slide_mm)?;
    let text = session.to_yaml_string(&format!(
        "Written by `alacs session init`: {} views at slide {} mm. Edit slide_mm per view\n\
         where views were taken at other slide positions (docs/FORMATS.md).",
        session.views.len(),
        args.slide_mm
    ));
    // Read back as every command will: the board and values are checked once, here.
    let path = args.dir.join(SESSION_FILE);
    Session::parse(&text, &args.dir, &path)?;
    if path.exists() && !args.force {
        return Err(Failure::bad_input(anyhow!(
            "{}: exists; pass --force to replace it",
            path.display()
        )));
    }
    write_file(&path, &text)?;
    let images: Vec<String> =
        session.views.iter().map(|v| v.image.to_string_lossy().into_owned()).collect();
    if args.json {
        output::print_json(&json!({
            "session": path.display().to_string(),
            "n_views": session.views.len(),
            "images": images,
        }))?;
    }
    errln!(
        "wrote {} ({} views, {}x{} board of {} x {} mm squares, slide {} mm)",
        path.display(),
        session.views.len(),
        cols,
        rows,
        square_x_mm,
        square_y_mm,
        args.slide_mm
    );
    Ok(())
}
