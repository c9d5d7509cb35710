//! The node's ROS 2 parameters and rcl_interfaces' six parameter services
//! (`<node>/list_parameters`, `get_parameters`, `get_parameter_types`,
//! `set_parameters`, `set_parameters_atomically`, `describe_parameters`),
//! so that `ros2 param list/get/set/describe` work. The services speak the
//! wire mapping `RMW_IMPLEMENTATION` names, as the action does
//! (ros2-client's own parameter services answer only one mapping).

use ros2_client::parameters::{ParameterValue, raw};
use ros2_client::rcl_interfaces::{
    DescribeParametersRequest, DescribeParametersResponse, GetParameterTypesRequest,
    GetParameterTypesResponse, GetParametersRequest, GetParametersResponse, ListParametersRequest,
    ListParametersResponse, ListParametersResult, SetParametersAtomicallyResponse,
    SetParametersRequest, SetParametersResponse,
};
use ros2_client::service::RmwRequestId;
use ros2_client::{Name, Node, Server, ServiceMapping, ServiceTypeName};

use crate::{Error, Result};

/// One parameter of the node: an option of `alacs ros` under its name with
/// underscores.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeParameter {
    /// The name (`camera_frame`).
    pub name: String,
    /// Its value (`NotSet` for an option without a value or default).
    pub value: ParameterValue,
    /// What it is (the option's help).
    pub description: String,
    /// Whether it is fixed for the node's life (read at start: the rig,
    /// the calibration, the names); the others apply to the next job.
    pub read_only: bool,
}

/// The node's parameters, by name.
#[derive(Debug, Clone, Default)]
pub struct Parameters {
    list: Vec<NodeParameter>,
}

/// The `ParameterType` number of a value.
fn type_of(value: &ParameterValue) -> u8 {
    raw::ParameterValue::from(value.clone()).ptype
}

impl Parameters {
    /// The parameters, sorted by name (a later one of a name replaces an
    /// earlier one).
    pub fn new(mut list: Vec<NodeParameter>) -> Self {
        list.sort_by(|a, b| a.name.cmp(&b.name));
        list.dedup_by(|later, earlier| {
            let same = later.name == earlier.name;
            if same {
                std::mem::swap(later, earlier);
            }
            same
        });
        Self { list }
    }

    /// The parameter `name`.
    pub fn get(&self, name: &str) -> Option<&NodeParameter> {
        self.list.iter().find(|p| p.name == name)
    }

    /// Whether `name` may take `value` now; the reason when not.
    fn check(&self, name: &str, value: &ParameterValue) -> std::result::Result<(), String> {
        let Some(parameter) = self.get(name) else {
            return Err(format!("no parameter `{name}` (ros2 param list shows them)"));
        };
        if parameter.read_only {
            return Err(format!(
                "`{name}` is read at start: restart the node with -p {name}:=VALUE"
            ));
        }
        if type_of(value) != type_of(&parameter.value) {
            return Err(format!(
                "`{name}` is a {}, not a {}",
                type_name(type_of(&parameter.value)),
                type_name(type_of(value))
            ));
        }
        match value {
            ParameterValue::Double(v) if !(v.is_finite() && *v >= 0.0) => {
                Err(format!("`{name}` must be a finite number from 0, not {v}"))
            }
            _ => Ok(()),
        }
    }

    /// Sets `name` to `value` if it may ([`Parameters::check`]).
    fn set(&mut self, name: &str, value: ParameterValue) -> std::result::Result<(), String> {
        self.check(name, &value)?;
        if let Some(parameter) = self.list.iter_mut().find(|p| p.name == name) {
            parameter.value = value;
        }
        Ok(())
    }

    fn descriptor(&self, name: &str) -> raw::ParameterDescriptor {
        let parameter = self.get(name);
        raw::ParameterDescriptor {
            name: name.to_owned(),
            r#type: parameter.map_or(0, |p| type_of(&p.value)),
            description: parameter.map_or_else(String::new, |p| p.description.clone()),
            additional_constraints: String::new(),
            read_only: parameter.is_none_or(|p| p.read_only),
            dynamic_typing: false,
            floating_point_range: Vec::new(),
            integer_range: Vec::new(),
        }
    }
}

/// ROS 2's name of a `ParameterType` number.
fn type_name(ptype: u8) -> &'static str {
    match ptype {
        1 => "bool",
        2 => "integer",
        3 => "double",
        4 => "string",
        5 => "byte array",
        6 => "bool array",
        7 => "integer array",
        8 => "double array",
        9 => "string array",
        _ => "value that is not set",
    }
}

/// One request to the parameter services.
pub enum ParameterRequest {
    /// `list_parameters`.
    List(RmwRequestId, ListParametersRequest),
    /// `get_parameters`.
    Get(RmwRequestId, GetParametersRequest),
    /// `get_parameter_types`.
    Types(RmwRequestId, GetParameterTypesRequest),
    /// `set_parameters`.
    Set(RmwRequestId, SetParametersRequest),
    /// `set_parameters_atomically`.
    SetAtomically(RmwRequestId, SetParametersRequest),
    /// `describe_parameters`.
    Describe(RmwRequestId, DescribeParametersRequest),
}

/// The six servers.
pub struct ParameterServices {
    list: Server<ListParametersRequest, ListParametersResponse>,
    get: Server<GetParametersRequest, GetParametersResponse>,
    types: Server<GetParameterTypesRequest, GetParameterTypesResponse>,
    set: Server<SetParametersRequest, SetParametersResponse>,
    set_atomically: Server<SetParametersRequest, SetParametersAtomicallyResponse>,
    describe: Server<DescribeParametersRequest, DescribeParametersResponse>,
}

impl ParameterServices {
    /// The services under the node's name (`<ns>/<node>/list_parameters`,
    /// ...), with rclcpp's parameter QoS (reliable, volatile).
    pub fn new(
        node: &mut Node,
        mapping: ServiceMapping,
        qos: &ros2_client::qos::QosProfile,
    ) -> Result<Self> {
        let fqn = node.fully_qualified_name();
        let server = |base: &str, type_name: &str| -> Result<(Name, ServiceTypeName)> {
            let name = Name::new(&fqn, base).map_err(|e| {
                Error::InvalidInput(format!("parameter service {fqn}/{base}: {e:?}"))
            })?;
            Ok((name, ServiceTypeName::new("rcl_interfaces", type_name)))
        };
        macro_rules! create {
            ($base:literal, $type:literal) => {{
                let (name, type_name) = server($base, $type)?;
                node.create_server(mapping, &name, &type_name, qos.clone(), qos.clone())
                    .map_err(|e| Error::dds("parameter service", e))?
            }};
        }
        Ok(Self {
            list: create!("list_parameters", "ListParameters"),
            get: create!("get_parameters", "GetParameters"),
            types: create!("get_parameter_types", "GetParameterTypes"),
            set: create!("set_parameters", "SetParameters"),
            set_atomically: create!("set_parameters_atomically", "SetParametersAtomically"),
            describe: create!("describe_parameters", "DescribeParameters"),
        })
    }

    /// The next request to any of the services (a failed read is skipped).
    pub async fn next(&self) -> ParameterRequest {
        use futures::FutureExt as _;
        loop {
            let request = futures::select! {
                r = self.list.async_receive_request().fuse() => r.map(|(id, q)| ParameterRequest::List(id, q)),
                r = self.get.async_receive_request().fuse() => r.map(|(id, q)| ParameterRequest::Get(id, q)),
                r = self.types.async_receive_request().fuse() => r.map(|(id, q)| ParameterRequest::Types(id, q)),
                r = self.set.async_receive_request().fuse() => r.map(|(id, q)| ParameterRequest::Set(id, q)),
                r = self.set_atomically.async_receive_request().fuse() => r.map(|(id, q)| ParameterRequest::SetAtomically(id, q)),
                r = self.describe.async_receive_request().fuse() => r.map(|(id, q)| ParameterRequest::Describe(id, q)),
            };
            if let Ok(request) = request {
                return request;
            }
        }
    }

    /// Answers `request` from `parameters`; the names it changed.
    pub async fn answer(
        &self,
        request: ParameterRequest,
        parameters: &mut Parameters,
    ) -> Vec<String> {
        let mut changed = Vec::new();
        match request {
            ParameterRequest::List(id, q) => {
                let names = parameters
                    .list
                    .iter()
                    .filter(|p| {
                        q.prefixes.is_empty()
                            || q.prefixes.iter().any(|x| p.name.starts_with(x.as_str()))
                    })
                    .map(|p| p.name.clone())
                    .collect();
                let result = ListParametersResult { names, prefixes: Vec::new() };
                let _ = self.list.async_send_response(id, ListParametersResponse { result }).await;
            }
            ParameterRequest::Get(id, q) => {
                let values = q
                    .names
                    .iter()
                    .map(|n| {
                        parameters.get(n).map_or(ParameterValue::NotSet, |p| p.value.clone()).into()
                    })
                    .collect();
                let _ = self.get.async_send_response(id, GetParametersResponse { values }).await;
            }
            ParameterRequest::Types(id, q) => {
                let values = q
                    .names
                    .iter()
                    .map(|n| parameters.get(n).map_or(0, |p| type_of(&p.value)))
                    .collect();
                let _ =
                    self.types.async_send_response(id, GetParameterTypesResponse { values }).await;
            }
            ParameterRequest::Set(id, q) => {
                let results = q
                    .parameter
                    .into_iter()
                    .map(|p| {
                        let result = parameters.set(&p.name, p.value.into());
                        if result.is_ok() {
                            changed.push(p.name);
                        }
                        set_result(result)
                    })
                    .collect();
                let _ = self.set.async_send_response(id, SetParametersResponse { results }).await;
            }
            ParameterRequest::SetAtomically(id, q) => {
                let all: Vec<(String, ParameterValue)> =
                    q.parameter.into_iter().map(|p| (p.name, p.value.into())).collect();
                let checked = all.iter().try_for_each(|(n, v)| parameters.check(n, v));
                if checked.is_ok() {
                    for (name, value) in all {
                        let _ = parameters.set(&name, value);
                        changed.push(name);
                    }
                }
                let result = set_result(checked);
                let _ = self
                    .set_atomically
                    .async_send_response(id, SetParametersAtomicallyResponse { result })
                    .await;
            }
            ParameterRequest::Describe(id, q) => {
                let values = q.names.iter().map(|n| parameters.descriptor(n)).collect();
                let _ = self
                    .describe
                    .async_send_response(id, DescribeParametersResponse { values })
                    .await;
            }
        }
        changed
    }
}

/// A set's result as rcl_interfaces says it.
fn set_result(result: std::result::Result<(), String>) -> raw::SetParametersResult {
    match result {
        Ok(()) => raw::SetParametersResult { successful: true, reason: String::new() },
        Err(reason) => raw::SetParametersResult { successful: false, reason },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parameter(name: &str, value: ParameterValue, read_only: bool) -> NodeParameter {
        NodeParameter { name: name.into(), value, description: String::new(), read_only }
    }

    #[test]
    fn only_writable_parameters_of_their_type_and_range_are_set() {
        let mut p = Parameters::new(vec![
            parameter("seed", ParameterValue::Integer(4), true),
            parameter("no_images", ParameterValue::Boolean(false), false),
            parameter("rough_depth_error", ParameterValue::Double(0.03), false),
        ]);
        assert!(p.set("no_images", ParameterValue::Boolean(true)).is_ok());
        assert_eq!(p.get("no_images").unwrap().value, ParameterValue::Boolean(true));
        assert!(p.set("seed", ParameterValue::Integer(5)).unwrap_err().contains("restart"));
        assert!(
            p.set("rough_depth_error", ParameterValue::Integer(1)).unwrap_err().contains("double")
        );
        assert!(p.set("rough_depth_error", ParameterValue::Double(-1.0)).is_err());
        assert!(p.set("nope", ParameterValue::Boolean(true)).unwrap_err().contains("`nope`"));
        assert_eq!(p.descriptor("seed").r#type, 2);
        assert!(p.descriptor("seed").read_only && !p.descriptor("no_images").read_only);
    }
}
