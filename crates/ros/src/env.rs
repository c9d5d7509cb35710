//! ROS 2's environment, read as ROS 2 reads it: the domain, how far
//! discovery reaches, and the RMW whose service wire mapping to speak.

use ros2_client::ServiceMapping;

use crate::{Error, Result};

/// The highest domain id whose RTPS ports fit in 16 bits (ROS 2's limit
/// on Linux is 101 for ephemeral-port reasons; the RTPS formula allows 232).
pub const MAX_DOMAIN_ID: u16 = 232;

/// What the node takes from the environment.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RosEnvironment {
    /// `ROS_DOMAIN_ID` (0 when unset or empty).
    pub domain_id: u16,
    /// Discovery and traffic on loopback only: `ROS_AUTOMATIC_DISCOVERY_RANGE`
    /// `LOCALHOST` (or `OFF`, approximated as localhost), else the
    /// deprecated `ROS_LOCALHOST_ONLY=1` when the range is unset.
    pub localhost_only: bool,
    /// The RMW whose conventions the node follows: `RMW_IMPLEMENTATION`,
    /// rmw_fastrtps_cpp when unset (ROS 2's default).
    pub rmw_implementation: String,
}

/// ROS 2's default RMW.
pub const DEFAULT_RMW: &str = "rmw_fastrtps_cpp";

impl RosEnvironment {
    /// Reads the process environment.
    pub fn from_env() -> Result<Self> {
        Self::from_lookup(|key| std::env::var(key).ok())
    }

    /// Reads the variables through `lookup` (a test passes a map).
    pub fn from_lookup(lookup: impl Fn(&str) -> Option<String>) -> Result<Self> {
        let bad = |key: &str, value: &str, why: &str| {
            Err(Error::InvalidInput(format!("environment variable {key}=`{value}`: {why}")))
        };
        let domain_id = match lookup("ROS_DOMAIN_ID").map(|v| v.trim().to_string()) {
            None => 0,
            Some(v) if v.is_empty() => 0,
            Some(v) => match v.parse::<u16>() {
                Ok(id) if id <= MAX_DOMAIN_ID => id,
                _ => return bad("ROS_DOMAIN_ID", &v, "must be a whole number from 0 to 232"),
            },
        };
        let range = lookup("ROS_AUTOMATIC_DISCOVERY_RANGE").map(|v| v.trim().to_ascii_uppercase());
        let localhost_only = match range.as_deref() {
            Some("LOCALHOST") | Some("OFF") => true,
            Some("SUBNET") | Some("SYSTEM_DEFAULT") => false,
            Some("") | None => lookup("ROS_LOCALHOST_ONLY").is_some_and(|v| v.trim() == "1"),
            Some(other) => {
                return bad(
                    "ROS_AUTOMATIC_DISCOVERY_RANGE",
                    other,
                    "must be SUBNET, LOCALHOST, OFF or SYSTEM_DEFAULT",
                );
            }
        };
        let rmw_implementation = lookup("RMW_IMPLEMENTATION")
            .map(|v| v.trim().to_string())
            .filter(|v| !v.is_empty())
            .unwrap_or_else(|| DEFAULT_RMW.to_string());
        Ok(Self { domain_id, localhost_only, rmw_implementation })
    }

    /// The service wire mapping of `rmw_implementation`: Cyclone DDS puts
    /// its own 16-byte request header in the payload; Fast DDS (ROS 2's
    /// default) and Connext carry the request id in inline QoS.
    pub fn service_mapping(&self) -> Result<ServiceMapping> {
        match self.rmw_implementation.as_str() {
            "rmw_cyclonedds_cpp" => Ok(ServiceMapping::Cyclone),
            "rmw_fastrtps_cpp" | "rmw_fastrtps_dynamic_cpp" | "rmw_connextdds" => {
                Ok(ServiceMapping::Enhanced)
            }
            other => Err(Error::InvalidInput(format!(
                "environment variable RMW_IMPLEMENTATION=`{other}`: the node speaks \
                 rmw_cyclonedds_cpp, rmw_fastrtps_cpp (the default) or rmw_connextdds"
            ))),
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use std::collections::HashMap;

    use super::*;

    fn read(pairs: &[(&str, &str)]) -> Result<RosEnvironment> {
        let map: HashMap<String, String> =
            pairs.iter().map(|(k, v)| ((*k).to_string(), (*v).to_string())).collect();
        RosEnvironment::from_lookup(|key| map.get(key).cloned())
    }

    #[test]
    fn the_environment_is_read_as_ros_2_reads_it() {
        let env = read(&[]).unwrap();
        assert_eq!((env.domain_id, env.localhost_only), (0, false));
        assert!(matches!(env.service_mapping().unwrap(), ServiceMapping::Enhanced));
        let env = read(&[("ROS_DOMAIN_ID", "42"), ("ROS_LOCALHOST_ONLY", "1")]).unwrap();
        assert_eq!((env.domain_id, env.localhost_only), (42, true));
        // The newer variable wins over the deprecated one.
        let env = read(&[("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET"), ("ROS_LOCALHOST_ONLY", "1")])
            .unwrap();
        assert!(!env.localhost_only);
        let env = read(&[("ROS_AUTOMATIC_DISCOVERY_RANGE", "localhost")]).unwrap();
        assert!(env.localhost_only);
        let env = read(&[("RMW_IMPLEMENTATION", "rmw_cyclonedds_cpp")]).unwrap();
        assert!(matches!(env.service_mapping().unwrap(), ServiceMapping::Cyclone));
    }

    #[test]
    fn bad_ros_environment_variables_are_refused_naming_them() {
        for (key, value) in [
            ("ROS_DOMAIN_ID", "abc"),
            ("ROS_DOMAIN_ID", "300"),
            ("ROS_AUTOMATIC_DISCOVERY_RANGE", "EVERYWHERE"),
        ] {
            let message = read(&[(key, value)]).unwrap_err().to_string();
            assert!(message.contains(key) && message.contains(value), "{message}");
        }
        let env = read(&[("RMW_IMPLEMENTATION", "rmw_zenoh_cpp")]).unwrap();
        let message = env.service_mapping().unwrap_err().to_string();
        assert!(message.contains("rmw_zenoh_cpp"), "{message}");
    }
}
