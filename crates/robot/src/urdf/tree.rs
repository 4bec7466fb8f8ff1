//! From parsed elements to a checked tree: names resolved to indices, one parent per link,
//! one root, no loop, mimic joints resolved to the joint they follow.

use super::parse::Parsed;
use super::{Joint, JointKind, Link, Mimic, UrdfError, UrdfModel};
use nalgebra::Unit;
use std::collections::HashMap;

pub(super) fn build(parsed: Parsed) -> Result<UrdfModel, UrdfError> {
    if parsed.links.is_empty() {
        return Err(UrdfError::NoLinks);
    }
    let mut link_index: HashMap<&str, usize> = HashMap::new();
    for (i, l) in parsed.links.iter().enumerate() {
        if let Some(&first) = link_index.get(l.name.as_str()) {
            return Err(UrdfError::Duplicate {
                what: "link",
                name: l.name.clone(),
                first_line: parsed.links[first].line,
                line: l.line,
            });
        }
        link_index.insert(&l.name, i);
    }
    let mut joint_index: HashMap<&str, usize> = HashMap::new();
    for (i, j) in parsed.joints.iter().enumerate() {
        if let Some(&first) = joint_index.get(j.name.as_str()) {
            return Err(UrdfError::Duplicate {
                what: "joint",
                name: j.name.clone(),
                first_line: parsed.joints[first].line,
                line: j.line,
            });
        }
        joint_index.insert(&j.name, i);
    }

    let mut parent_joint: Vec<Option<usize>> = vec![None; parsed.links.len()];
    let mut joints = Vec::with_capacity(parsed.joints.len());
    for (ji, j) in parsed.joints.iter().enumerate() {
        let find = |role: &'static str, name: &str| {
            link_index
                .get(name)
                .copied()
                .ok_or_else(|| UrdfError::UnknownLink {
                    joint: j.name.clone(),
                    role,
                    link: name.to_owned(),
                })
        };
        let parent = find("parent", &j.parent)?;
        let child = find("child", &j.child)?;
        if parent == child {
            return Err(UrdfError::Loop {
                link: j.child.clone(),
            });
        }
        if let Some(first) = parent_joint[child] {
            return Err(UrdfError::TwoParents {
                link: j.child.clone(),
                first: parsed.joints[first].name.clone(),
                second: j.name.clone(),
            });
        }
        parent_joint[child] = Some(ji);
        let norm = j.axis.norm();
        // Only movable joints use their axis; a fixed joint's axis is never read.
        let axis = if j.kind.is_movable() {
            if norm == 0.0 || !norm.is_finite() {
                return Err(UrdfError::ZeroAxis {
                    joint: j.name.clone(),
                    line: j.axis_line,
                });
            }
            Unit::new_normalize(j.axis)
        } else {
            Unit::new_normalize(if norm > 0.0 {
                j.axis
            } else {
                nalgebra::Vector3::x()
            })
        };
        joints.push(Joint {
            name: j.name.clone(),
            kind: j.kind,
            parent,
            child,
            origin: j.origin,
            axis,
            limits: j.limits,
            mimic: None,
        });
    }

    let roots: Vec<usize> = (0..parsed.links.len())
        .filter(|&l| parent_joint[l].is_none())
        .collect();
    if roots.is_empty() {
        // Every link has a parent: following parents from any link must cycle.
        return Err(UrdfError::Loop {
            link: parsed.links[0].name.clone(),
        });
    }
    if roots.len() > 1 {
        return Err(UrdfError::SeveralRoots {
            roots: roots
                .iter()
                .take(16)
                .map(|&l| parsed.links[l].name.clone())
                .collect(),
        });
    }
    let root = roots[0];

    // Breadth first from the root: the order forward kinematics visits joints. A link not
    // reached has a parent chain that never reaches the root, hence a loop.
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); parsed.links.len()];
    for (ji, j) in joints.iter().enumerate() {
        children[j.parent].push(ji);
    }
    let mut order = Vec::with_capacity(joints.len());
    let mut reached = vec![false; parsed.links.len()];
    reached[root] = true;
    let mut queue = std::collections::VecDeque::from([root]);
    while let Some(l) = queue.pop_front() {
        for &ji in &children[l] {
            let c = joints[ji].child;
            reached[c] = true;
            order.push(ji);
            queue.push_back(c);
        }
    }
    if let Some(l) = reached.iter().position(|r| !r) {
        return Err(UrdfError::Loop {
            link: parsed.links[l].name.clone(),
        });
    }

    resolve_mimics(&parsed, &joint_index, &mut joints)?;

    let links = parsed
        .links
        .into_iter()
        .zip(parent_joint)
        .map(|(l, parent_joint)| Link {
            name: l.name,
            collisions: l.collisions,
            parent_joint,
        })
        .collect();
    Ok(UrdfModel {
        name: parsed.name,
        links,
        joints,
        root,
        order,
    })
}

/// Resolves each mimic to the joint it names, and refuses unknown, fixed and cyclic targets.
/// A chain of mimics (a follows b follows c) is kept as written; kinematics composes it.
fn resolve_mimics(
    parsed: &Parsed,
    joint_index: &HashMap<&str, usize>,
    joints: &mut [Joint],
) -> Result<(), UrdfError> {
    for (ji, j) in parsed.joints.iter().enumerate() {
        let Some((target, multiplier, offset)) = &j.mimic else {
            continue;
        };
        if !j.kind.is_movable() {
            continue; // a mimic on a fixed joint has nothing to drive
        }
        let Some(&t) = joint_index.get(target.as_str()) else {
            return Err(UrdfError::MimicUnknownJoint {
                joint: j.name.clone(),
                target: target.clone(),
            });
        };
        if joints[t].kind == JointKind::Fixed {
            return Err(UrdfError::MimicOfFixed {
                joint: j.name.clone(),
                target: target.clone(),
            });
        }
        joints[ji].mimic = Some(Mimic {
            joint: t,
            multiplier: *multiplier,
            offset: *offset,
        });
    }
    for start in 0..joints.len() {
        let mut at = start;
        let mut steps = 0;
        while let Some(m) = &joints[at].mimic {
            at = m.joint;
            steps += 1;
            if steps > joints.len() {
                return Err(UrdfError::MimicCycle {
                    joint: joints[start].name.clone(),
                });
            }
        }
    }
    Ok(())
}
