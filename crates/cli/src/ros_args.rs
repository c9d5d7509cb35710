//! `alacs ros ... --ros-args ...`: the arguments ROS 2 gives a node
//! (`ros2 run`, launch files), read as rclcpp reads them and turned into
//! `alacs ros`'s own options before the command line is parsed:
//!
//! - `-p NAME:=VALUE` (`--param`): the option `--NAME` (underscores as
//!   hyphens) with VALUE, a YAML scalar as ROS parses it; `true` sets a
//!   flag, `false` leaves it unset; a list is comma-joined. Every option of
//!   `alacs ros` is a parameter of the same name (`camera_frame`, `sim`,
//!   `seed`, `rig`, ...).
//! - `--params-file FILE`: the `ros__parameters` of the file's sections
//!   that name the node (`/**`, its name, `/NS/NAME`, `/**/NAME`), read
//!   before `-p`, which override them.
//! - `-r __ns:=NS`, `-r __node:=NAME` (`__name`): the namespace and the
//!   node's name; `-r FROM:=TO` (`--remap`): one of the node's topics or
//!   its action under another name.
//! - `--log-level LEVEL`: accepted; the node logs on standard error.
//! - `--`: the end of the ROS arguments; anything else is refused, naming it.

use std::ffi::OsString;
use std::path::Path;

use serde_json::Value;

/// The most a parameters file may hold, bytes (a node's file is a few KB).
const MAX_PARAMS_FILE_BYTES: u64 = 1 << 20;

/// `args` (the program's, its name first) with any `--ros-args` section
/// turned into `alacs ros` options (see the module docs); unchanged
/// without one. `options` are the long options `alacs ros` takes.
pub fn expand(args: Vec<OsString>, options: &[String]) -> Result<Vec<OsString>, String> {
    let Some(start) = args.iter().position(|a| a == "--ros-args") else { return Ok(args) };
    if args.get(1).is_none_or(|a| a != "ros") {
        return Err("--ros-args is for `alacs ros` (the ROS 2 node)".into());
    }
    let text = |a: &OsString| {
        a.to_str().map(str::to_owned).ok_or_else(|| format!("{a:?} in --ros-args is not UTF-8"))
    };
    let mut out: Vec<OsString> = args[..start].to_vec();
    let mut params: Vec<(String, Value)> = Vec::new();
    let mut files: Vec<String> = Vec::new();
    let mut remaps: Vec<(String, String)> = Vec::new();
    let mut i = start + 1;
    while i < args.len() {
        let token = text(&args[i])?;
        let value = |k: usize| -> Result<String, String> {
            args.get(k)
                .map(text)
                .transpose()?
                .ok_or_else(|| format!("--ros-args {token}: a value must follow"))
        };
        match token.as_str() {
            "--" => {
                out.extend(args[i + 1..].iter().cloned());
                break;
            }
            "--ros-args" => {}
            "-p" | "--param" => {
                let item = value(i + 1)?;
                let (name, raw) = split_assignment(&item, &token)?;
                params.push((name, parse_scalar(&raw)));
                i += 1;
            }
            "--params-file" => {
                files.push(value(i + 1)?);
                i += 1;
            }
            "-r" | "--remap" => {
                let item = value(i + 1)?;
                remaps.push(split_assignment(&item, &token)?);
                i += 1;
            }
            "--log-level" => {
                value(i + 1)?;
                i += 1;
            }
            other => {
                return Err(format!(
                    "--ros-args: `{other}` is not supported (alacs ros takes -p, --params-file, -r and --log-level)"
                ));
            }
        }
        i += 1;
    }
    // The node's name and namespace, for the file's sections: remapped, else
    // given as options, else the defaults.
    let given = |option: &str, default: &str| {
        out.iter()
            .position(|a| a == option)
            .and_then(|k| out.get(k + 1))
            .and_then(|v| v.to_str())
            .unwrap_or(default)
            .to_owned()
    };
    let remapped =
        |key: &[&str]| remaps.iter().find(|(f, _)| key.contains(&f.as_str())).map(|r| r.1.clone());
    let node = remapped(&["__node", "__name"]).unwrap_or_else(|| given("--node-name", "alacs"));
    let namespace = remapped(&["__ns"]).unwrap_or_else(|| given("--namespace", "/alacs"));
    let mut all: Vec<(String, Value)> = Vec::new();
    for file in &files {
        all.extend(read_params_file(Path::new(file), &node, &namespace)?);
    }
    all.extend(params);
    // A parameter given twice takes its last value, at its first place.
    let mut last: Vec<(String, Value)> = Vec::new();
    for (name, value) in all {
        match last.iter_mut().find(|(n, _)| *n == name) {
            Some(slot) => slot.1 = value,
            None => last.push((name, value)),
        }
    }
    for (name, value) in last {
        let option = format!("--{}", name.replace('_', "-"));
        if !options.contains(&option) || ["--help", "--json"].contains(&option.as_str()) {
            return Err(format!(
                "parameter `{name}` is not one of alacs ros's (each option is a parameter: {})",
                options
                    .iter()
                    .filter(|o| !["--help", "--json"].contains(&o.as_str()))
                    .map(|o| o.trim_start_matches("--").replace('-', "_"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        match value {
            Value::Bool(true) => out.push(option.into()),
            Value::Bool(false) | Value::Null => {}
            Value::Array(items) => {
                let joined: Vec<String> = items.iter().map(scalar_text).collect();
                out.push(format!("{option}={}", joined.join(",")).into());
            }
            other => out.push(format!("{option}={}", scalar_text(&other)).into()),
        }
    }
    for (from, to) in remaps {
        match from.as_str() {
            "__ns" => out.push(format!("--namespace={to}").into()),
            "__node" | "__name" => out.push(format!("--node-name={to}").into()),
            _ => out.push(format!("--remap={from}:={to}").into()),
        }
    }
    Ok(out)
}

/// `NAME:=VALUE` of the ROS argument `flag`.
fn split_assignment(item: &str, flag: &str) -> Result<(String, String), String> {
    match item.split_once(":=") {
        Some((name, value)) if !name.is_empty() => Ok((name.to_owned(), value.to_owned())),
        _ => Err(format!("--ros-args {flag} `{item}`: NAME:=VALUE")),
    }
}

/// A `-p` value as ROS reads it: a YAML scalar (or list).
fn parse_scalar(raw: &str) -> Value {
    serde_saphyr::from_str::<Value>(raw).unwrap_or_else(|_| Value::String(raw.to_owned()))
}

/// A scalar as an option's value.
fn scalar_text(value: &Value) -> String {
    match value {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// The parameters of `path` for the node `node` in `namespace`: the
/// `ros__parameters` maps of its sections `/**`, `NODE`, `/NS/NODE` and
/// `/**/NODE`, in the file's order (nested maps flattened with dots, as
/// ROS names them).
pub fn read_params_file(
    path: &Path,
    node: &str,
    namespace: &str,
) -> Result<Vec<(String, Value)>, String> {
    let name = path.display();
    let bytes = alacs::model::io::read_bytes_bounded(path, MAX_PARAMS_FILE_BYTES)
        .map_err(|e| format!("--params-file: {e}"))?;
    let text = String::from_utf8(bytes).map_err(|_| format!("--params-file {name}: not UTF-8"))?;
    let root: Value = serde_saphyr::from_str(&text).map_err(|e| {
        format!("--params-file {name}: not YAML: {}", alacs::model::yaml_message(&e))
    })?;
    let Value::Object(sections) = root else {
        return Err(format!(
            "--params-file {name}: a map of node names to ros__parameters, as ROS 2 writes it"
        ));
    };
    let ns = namespace.trim_end_matches('/');
    let matches = |key: &str| {
        let key = key.trim();
        key == "/**"
            || key == node
            || key == format!("{ns}/{node}")
            || key == format!("/**/{node}")
            || key == format!("{}/{node}", ns.trim_start_matches('/'))
    };
    let mut found = Vec::new();
    for (key, section) in &sections {
        if !matches(key) {
            continue;
        }
        let Some(Value::Object(parameters)) = section.get("ros__parameters") else {
            return Err(format!(
                "--params-file {name}: section `{key}` holds no ros__parameters map"
            ));
        };
        flatten("", parameters, &mut found);
    }
    Ok(found)
}

/// Nested parameter maps as ROS names them: `outer.inner`.
fn flatten(prefix: &str, map: &serde_json::Map<String, Value>, out: &mut Vec<(String, Value)>) {
    for (key, value) in map {
        let name = if prefix.is_empty() { key.clone() } else { format!("{prefix}.{key}") };
        match value {
            Value::Object(inner) => flatten(&name, inner, out),
            other => out.push((name, other.clone())),
        }
    }
}

/// Every option of `alacs ros` (`command`) as the node's ROS 2 parameter
/// (the names `-p` takes): flags as bools, numbers as integers or doubles
/// by their parser, lists (comma-separated options) as string arrays, the
/// rest as strings; an option without a value or default is not set. The
/// description is the option's help.
pub fn parameters(
    command: &clap::Command,
    matches: &clap::ArgMatches,
) -> Vec<alacs::ros::NodeParameter> {
    use alacs::ros::ParameterValue;
    use clap::builder::ValueParser;
    let of = |parser: &ValueParser, id: std::any::TypeId| parser.type_id() == id;
    command
        .get_arguments()
        .filter_map(|arg| {
            let long = arg.get_long()?;
            let id = arg.get_id().as_str();
            let value = match arg.get_action() {
                clap::ArgAction::SetTrue => ParameterValue::Boolean(matches.get_flag(id)),
                action if action.takes_values() => {
                    let raw: Vec<String> = matches
                        .get_raw(id)
                        .map(|values| values.map(|v| v.to_string_lossy().into_owned()).collect())
                        .unwrap_or_default();
                    let parser = arg.get_value_parser();
                    let list = arg.get_value_delimiter().is_some()
                        || matches!(action, clap::ArgAction::Append);
                    let integer = [
                        std::any::TypeId::of::<u64>(),
                        std::any::TypeId::of::<u32>(),
                        std::any::TypeId::of::<usize>(),
                        std::any::TypeId::of::<i64>(),
                        std::any::TypeId::of::<u16>(),
                        std::any::TypeId::of::<u8>(),
                    ];
                    match raw.as_slice() {
                        [] => ParameterValue::NotSet,
                        _ if list => ParameterValue::StringArray(raw),
                        [one] if of(parser, std::any::TypeId::of::<f64>()) => {
                            one.parse().map_or_else(
                                |_| ParameterValue::String(one.clone()),
                                ParameterValue::Double,
                            )
                        }
                        [one] if integer.iter().any(|&t| of(parser, t)) => one.parse().map_or_else(
                            |_| ParameterValue::String(one.clone()),
                            ParameterValue::Integer,
                        ),
                        [one] => ParameterValue::String(one.clone()),
                        _ => ParameterValue::StringArray(raw),
                    }
                }
                _ => return None, // --help, --version
            };
            Some(alacs::ros::NodeParameter {
                name: long.replace('-', "_"),
                value,
                description: arg.get_help().map(ToString::to_string).unwrap_or_default(),
                read_only: true,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn os(args: &[&str]) -> Vec<OsString> {
        args.iter().map(OsString::from).collect()
    }

    fn options() -> Vec<String> {
        [
            "--sim",
            "--seed",
            "--camera-frame",
            "--namespace",
            "--node-name",
            "--no-images",
            "--remap",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .collect()
    }

    #[test]
    fn parameters_and_remaps_become_options() {
        let args = os(&[
            "alacs",
            "ros",
            "--ros-args",
            "-p",
            "sim:=true",
            "-p",
            "seed:=7",
            "-p",
            "no_images:=false",
            "-p",
            "camera_frame:=cam_optical",
            "-r",
            "__ns:=/left",
            "-r",
            "__node:=alacs_left",
            "-r",
            "fruit:=/harvester/fruit",
            "--log-level",
            "info",
        ]);
        let out = expand(args, &options()).unwrap();
        let out: Vec<&str> = out.iter().map(|a| a.to_str().unwrap()).collect();
        assert_eq!(
            out,
            [
                "alacs",
                "ros",
                "--sim",
                "--seed=7",
                "--camera-frame=cam_optical",
                "--namespace=/left",
                "--node-name=alacs_left",
                "--remap=fruit:=/harvester/fruit"
            ]
        );
    }

    #[test]
    fn unknown_parameters_and_arguments_are_refused_by_name() {
        let e =
            expand(os(&["alacs", "ros", "--ros-args", "-p", "nope:=1"]), &options()).unwrap_err();
        assert!(e.contains("`nope`") && e.contains("camera_frame"), "{e}");
        let e =
            expand(os(&["alacs", "ros", "--ros-args", "--enclave", "/x"]), &options()).unwrap_err();
        assert!(e.contains("--enclave"), "{e}");
        let e = expand(os(&["alacs", "scan", "--ros-args"]), &options()).unwrap_err();
        assert!(e.contains("alacs ros"), "{e}");
        let e = expand(os(&["alacs", "ros", "--ros-args", "-p", "seed"]), &options()).unwrap_err();
        assert!(e.contains("NAME:=VALUE"), "{e}");
    }

    #[test]
    fn a_params_file_gives_the_nodes_sections_and_p_overrides_it() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("params.yaml");
        std::fs::write(
            &file,
            "/**:\n  ros__parameters:\n    seed: 3\n    sim: true\nalacs_left:\n  ros__parameters:\n    camera_frame: left_optical\nalacs_right:\n  ros__parameters:\n    camera_frame: right_optical\n",
        )
        .unwrap();
        let args = os(&[
            "alacs",
            "ros",
            "--ros-args",
            "-r",
            "__node:=alacs_left",
            "--params-file",
            file.to_str().unwrap(),
            "-p",
            "seed:=9",
        ]);
        let out = expand(args, &options()).unwrap();
        let out: Vec<&str> = out.iter().map(|a| a.to_str().unwrap()).collect();
        assert_eq!(
            out,
            [
                "alacs",
                "ros",
                "--seed=9",
                "--sim",
                "--camera-frame=left_optical",
                "--node-name=alacs_left"
            ]
        );
    }

    /// The repository's parameters files (ros/alacs_bringup/config) give
    /// each node a command line `alacs ros` takes, and the launch files
    /// parse (Python's own parser, XML by Python's).
    #[test]
    fn the_bringup_packages_parameters_and_launch_files_parse() {
        use clap::{CommandFactory as _, Parser as _};
        let command = crate::args::Cli::command();
        let options: Vec<String> = command
            .find_subcommand("ros")
            .unwrap()
            .get_arguments()
            .filter_map(|a| a.get_long())
            .map(|l| format!("--{l}"))
            .collect();
        let bringup = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../ros/alacs_bringup");
        for (file, nodes) in
            [("alacs.yaml", &["alacs"][..]), ("two_units.yaml", &["alacs_left", "alacs_right"][..])]
        {
            let path = bringup.join("config").join(file);
            for node in nodes {
                let args = os(&[
                    "alacs",
                    "ros",
                    "--ros-args",
                    "-r",
                    &format!("__node:={node}"),
                    "-r",
                    &format!("__ns:=/{node}"),
                    "--params-file",
                    path.to_str().unwrap(),
                ]);
                let out = expand(args, &options).unwrap_or_else(|e| panic!("{file} {node}: {e}"));
                let cli = crate::args::Cli::try_parse_from(&out)
                    .unwrap_or_else(|e| panic!("{file} {node}: {out:?}: {e}"));
                let crate::args::Command::Ros(ros) = cli.command else { panic!("not ros") };
                assert_eq!(ros.node_name, *node);
                if *node != "alacs" {
                    assert_eq!(ros.camera_frame, format!("{node}_camera_optical_frame"));
                }
            }
        }
        let python = std::process::Command::new("python3").arg("--version").output();
        if python.is_err() {
            eprintln!("no python3: the launch files' syntax is not checked");
            return;
        }
        for launch in ["alacs.launch.py", "two_units.launch.py", "alacs.launch.xml"] {
            let path = bringup.join("launch").join(launch);
            let check = if launch.ends_with(".py") {
                "import ast, sys; ast.parse(open(sys.argv[1]).read())"
            } else {
                "import sys, xml.etree.ElementTree as e; r = e.parse(sys.argv[1]).getroot(); assert r.tag == 'launch' and r.find('node') is not None"
            };
            let status = std::process::Command::new("python3")
                .args(["-c", check])
                .arg(&path)
                .status()
                .unwrap();
            assert!(status.success(), "{launch} does not parse");
        }
    }
}
