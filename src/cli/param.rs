//! `chronotope param`: read or set a running node's parameters over the ROS parameter
//! services (`/node/get_parameters`, `/node/set_parameters`), as `ros2 param get/set` does,
//! without a ROS installation. Works with the suite's nodes and any ROS 2 node on the domain.

use std::time::Duration;

use clap::{Args, Subcommand};
use ros2_client::parameters::raw;
use ros2_client::qos::History;
use ros2_client::rcl_interfaces::{
    GetParametersRequest, GetParametersResponse, SetParametersRequest, SetParametersResponse,
};
use ros2_client::{Name, Parameter, ParameterValue, QosProfile, ServiceMapping, ServiceTypeName};

use super::CliError;
use crate::live::{domain_id_from_env, ros_param, Participant};
use crate::node::launch::ParamValue;

/// Options of `chronotope param`.
#[derive(Debug, Clone, Args)]
pub struct ParamArgs {
    /// Get or set.
    #[command(subcommand)]
    pub action: ParamAction,
    /// Seconds to wait for the node's parameter service.
    #[arg(long, default_value_t = 10.0, global = true)]
    pub timeout: f64,
}

/// What to do.
#[derive(Debug, Clone, Subcommand)]
pub enum ParamAction {
    /// Print parameters of a running node (`/mesher idle_timeout_s`).
    Get {
        /// The node's fully qualified name.
        node: String,
        /// Parameter names.
        #[arg(required = true)]
        names: Vec<String>,
    },
    /// Set a parameter of a running node; the node applies it or says why not.
    Set {
        /// The node's fully qualified name.
        node: String,
        /// Parameter name.
        name: String,
        /// New value, in YAML (`0.5`, `-1`, `true`, `[1, 2]`, `text`).
        #[arg(allow_hyphen_values = true)]
        value: String,
    },
}

/// `chronotope param`.
///
/// # Errors
/// Bad arguments, no answer within the timeout, or the node refused (with its reason).
pub fn run(a: &ParamArgs) -> Result<(), CliError> {
    if !(a.timeout.is_finite() && (0.0..=3600.0).contains(&a.timeout)) {
        return Err(CliError::Usage(format!(
            "--timeout {}: not a number of seconds in [0, 3600]",
            a.timeout
        )));
    }
    let timeout = Duration::from_secs_f64(a.timeout);
    let node = match &a.action {
        ParamAction::Get { node, .. } | ParamAction::Set { node, .. } => node.clone(),
    };
    let target = node.trim_end_matches('/');
    if !target.starts_with('/') || target.len() < 2 {
        return Err(CliError::Usage(format!(
            "{node}: give the node's fully qualified name (`/mesher`, `/cell/checker`)"
        )));
    }
    let participant = Participant::new(domain_id_from_env()?)?;
    let mut me = participant.ros_node(
        &format!("/chronotope_param_{}", std::process::id()),
        &Default::default(),
        None,
    )?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .map_err(crate::live::LiveError::Runtime)?;
    let spinner = me
        .spinner()
        .map_err(|e| CliError::Usage(format!("ros2-client: {e:?}")))?;
    runtime.spawn(async move {
        let _ = spinner.spin().await;
    });
    let qos = QosProfile::publisher_default().history(History::KeepLast { depth: 1 });
    let service =
        |leaf: &str| Name::new(target, leaf).map_err(|e| CliError::Usage(format!("{node}: {e:?}")));
    let no_answer = || {
        CliError::Usage(format!(
            "{target}: no answer from its parameter service within {:.0} s (is it running on \
             ROS_DOMAIN_ID {}?)",
            a.timeout,
            participant.domain_id()
        ))
    };
    match &a.action {
        ParamAction::Get { names, .. } => {
            let values = get(
                &mut me,
                &runtime,
                &service("get_parameters")?,
                names.clone(),
                timeout,
            )
            .map_err(|e| match e {
                None => no_answer(),
                Some(e) => CliError::Usage(format!("{target}: {e}")),
            })?;
            for (name, v) in names.iter().zip(values) {
                match v {
                    ParameterValue::NotSet => println!("{name}: not set"),
                    v => println!("{name}: {v:?}"),
                }
            }
            Ok(())
        }
        ParamAction::Set { name, value, .. } => {
            // The same bounds as a launch config: a hostile argument is refused by the
            // limit's name before it is parsed.
            let yaml: serde_yaml_ng::Value =
                crate::yaml::from_str(value, &crate::yaml::CONFIG_LIMITS).map_err(|e| {
                    CliError::Usage(format!(
                        "{name} {}: not a YAML value: {e}",
                        crate::yaml::quote(value)
                    ))
                })?;
            let mut v = ParamValue::from_yaml(&yaml).ok_or_else(|| {
                CliError::Usage(format!(
                    "{name} {}: not a parameter value (a number, bool, string or a list of one kind)",
                    crate::yaml::quote(value)
                ))
            })?;
            if let ParamValue::Integer(i) = v {
                // `1` for a double parameter means 1.0 (ROS refuses to change a type).
                let now = get(
                    &mut me,
                    &runtime,
                    &service("get_parameters")?,
                    vec![name.clone()],
                    timeout,
                );
                if let Ok([ParameterValue::Double(_)]) = now.as_deref() {
                    v = ParamValue::Double(i as f64);
                }
            }
            let client = me
                .create_client::<SetParametersRequest, SetParametersResponse>(
                    ServiceMapping::Enhanced,
                    &service("set_parameters")?,
                    &ServiceTypeName::new("rcl_interfaces", "SetParameters"),
                    qos.clone(),
                    qos,
                )
                .map_err(|e| CliError::Usage(format!("ros2-client: {e:?}")))?;
            let req = SetParametersRequest {
                parameter: vec![raw::Parameter::from(Parameter {
                    name: name.clone(),
                    value: ros_param(&v),
                })],
            };
            let resp = runtime
                .block_on(async {
                    tokio::time::timeout(timeout, async {
                        client.wait_for_service(&me).await;
                        client.async_call_service(req).await
                    })
                    .await
                })
                .map_err(|_| no_answer())?
                .map_err(|e| CliError::Usage(format!("{target}: {e:?}")))?;
            match resp.results.first() {
                Some(r) if r.successful => {
                    println!("{target} {name}: set");
                    Ok(())
                }
                Some(r) => Err(CliError::Usage(format!(
                    "{target} {name}: refused: {}",
                    r.reason
                ))),
                None => Err(CliError::Usage(format!("{target} {name}: an empty answer"))),
            }
        }
    }
}

/// The values of parameters `names` of the node whose `get_parameters` service is `service`;
/// `Err(None)` when no answer came within `timeout`.
fn get(
    me: &mut ros2_client::Node,
    runtime: &tokio::runtime::Runtime,
    service: &Name,
    names: Vec<String>,
    timeout: Duration,
) -> Result<Vec<ParameterValue>, Option<String>> {
    let qos = QosProfile::publisher_default().history(History::KeepLast { depth: 1 });
    let client = me
        .create_client::<GetParametersRequest, GetParametersResponse>(
            ServiceMapping::Enhanced,
            service,
            &ServiceTypeName::new("rcl_interfaces", "GetParameters"),
            qos.clone(),
            qos,
        )
        .map_err(|e| Some(format!("ros2-client: {e:?}")))?;
    let resp = runtime
        .block_on(async {
            tokio::time::timeout(timeout, async {
                client.wait_for_service(me).await;
                client
                    .async_call_service(GetParametersRequest { names })
                    .await
            })
            .await
        })
        .map_err(|_| None)?
        .map_err(|e| Some(format!("{e:?}")))?;
    Ok(resp.values.into_iter().map(ParameterValue::from).collect())
}
