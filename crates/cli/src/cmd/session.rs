//! `alacs session init`: session.yaml for a folder of board images.

use alacs::Session;
use alacs::model::io::write_file;
use alacs::model::{BoardSpec, CharucoMarkers, SESSION_FILE};
use anyhow::anyhow;
use serde_json::json;

use crate::args::SessionInitArgs;
use crate::cmd::simulate::{parse_dictionary, parse_list};
use crate::failure::{CmdResult, Failure};
use crate::output;

/// Parses `COLSxROWS` (e.g. `9x6`).
fn parse_board(text: &str) -> CmdResult<(usize, usize)> {
    let parsed = text.split_once(['x', 'X']).and_then(|(c, r)| {
        Some((c.trim().parse::<usize>().ok()?, r.trim().parse::<usize>().ok()?))
    });
    let range = alacs::model::INNER_CORNERS_RANGE;
    match parsed {
        Some((cols, rows)) if range.contains(&cols) && range.contains(&rows) => Ok((cols, rows)),
        Some(_) => Err(Failure::bad_input(anyhow!(
            "--board `{text}`: a board has {}-{} inner corners along each side",
            range.start(),
            range.end()
        ))),
        None => Err(Failure::bad_input(anyhow!(
            "--board takes COLSxROWS inner corners (e.g. 9x6), got `{text}`"
        ))),
    }
}

/// Runs `alacs session init`.
pub fn init(args: &SessionInitArgs) -> CmdResult {
    let (cols, rows) = parse_board(&args.board)?;
    let (square_x_mm, square_y_mm) = match *parse_list(&args.square_mm, "--square-mm")?.as_slice() {
        [s] => (s, s),
        [x, y] => (x, y),
        _ => {
            return Err(Failure::bad_input(anyhow!(
                "--square-mm takes S or X,Y in mm, got `{}`",
                args.square_mm
            )));
        }
    };
    let limit = alacs::model::MAX_SQUARE_MM;
    if ![square_x_mm, square_y_mm].iter().all(|s| *s > 0.0 && *s <= limit) {
        return Err(Failure::bad_input(anyhow!(
            "--square-mm `{}`: a square must lie in (0, {limit}] mm",
            args.square_mm
        )));
    }
    let mut board = BoardSpec::checkerboard(cols, rows, square_x_mm, square_y_mm);
    if let (Some(name), Some(marker_mm)) = (&args.charuco, args.marker_mm) {
        let dictionary = parse_dictionary(name)?;
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
