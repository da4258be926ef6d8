//! The database's skeleton from the reference take: joint roles, rest geometry, the `.mmdb`
//! skeleton with the virtual root as joint 0 and a site per role, left/right pairs for
//! mirroring; and the check that every other take shares its topology.

use super::sample::sample_poses;
use super::{Source, VIRTUAL_ROOT};
use crate::bvh::{Bvh, Channel};
use crate::config::BuildConfig;
use crate::database::{Site, Skeleton};
use crate::error::{Error, Result};
use crate::kinematics::local_to_model;
use crate::roles::{self, Role, Roles, Shape};
use glam::{DQuat, DVec3, Vec3};

/// Roles without which no database can be built.
const REQUIRED: [Role; 5] = [Role::Hips, Role::LeftUpperLeg, Role::RightUpperLeg, Role::LeftFoot, Role::RightFoot];

/// What every take is measured against: the reference take's names, hierarchy and roles. The
/// same description serves another skeleton's takes (`super::retarget`).
pub struct Reference {
    pub names: Vec<String>,
    /// Parent per BVH joint, negative for the root.
    pub parents: Vec<i32>,
    pub roles: Roles,
    /// The opposite-side joint of each joint (itself for centre joints), for mirroring.
    pub pairs: Vec<usize>,
    /// Joints whose translation is animated (root motion); the others keep the rest offset.
    pub animated_translation: Vec<bool>,
}

impl Reference {
    /// Reads a take's skeleton and finds its roles: config overrides first (those naming joints
    /// this skeleton has), then names checked against the topology and the geometry of poses
    /// sampled from the motion in `frames` (`roles::find_roles_in`).
    ///
    /// # Errors
    /// A bad role override, or a required role (hips, upper legs, feet) that cannot be found:
    /// the message says which part the geometry did not find either.
    pub fn new(config: &BuildConfig, source: &Source, frames: (usize, usize), is_reference: bool) -> Result<Reference> {
        let bvh = &source.bvh;
        let names: Vec<String> = bvh.joints.iter().map(|j| j.name.clone()).collect();
        let parents: Vec<i32> = bvh.joints.iter().map(|j| j.parent.map_or(-1, |p| p as i32)).collect();
        let offsets: Vec<DVec3> = bvh.joints.iter().map(|j| j.offset).collect();
        let end_sites: Vec<Option<DVec3>> = bvh.joints.iter().map(|j| j.end_site).collect();
        let poses = sample_poses(bvh, frames, 16);
        let shape = Shape { offsets: &offsets, end_sites: &end_sites, poses: &poses };
        let mut overrides: std::collections::HashMap<String, String> = if is_reference {
            config.roles.clone()
        } else {
            // Overrides describe the reference skeleton; another skeleton keeps those that fit.
            let known: Vec<String> = names.iter().map(|n| roles::normalize_name(n)).collect();
            config
                .roles
                .iter()
                .filter(|(_, j)| j.is_empty() || known.contains(&roles::normalize_name(j)))
                .map(|(r, j)| (r.clone(), j.clone()))
                .collect()
        };
        // The file's own map (a VRM humanoid), under the config's.
        for (role, joint) in &bvh.role_hints {
            overrides.entry(role.clone()).or_insert_with(|| joint.clone());
        }
        let roles = roles::find_roles_in(&names, &parents, Some(&shape), &overrides)
            .map_err(|e| Error::config(format!("roles: {e}")))?;
        let humanoid = roles::find_humanoid(&parents, &shape);
        for role in REQUIRED {
            if !roles.contains(role) {
                let why = match &humanoid {
                    Err(e) => format!("not a humanoid skeleton: {e}"),
                    Ok(_) => format!("could not find the {} joint", role.name().replace('_', " ")),
                };
                // The hint first: the message is capped, the name list may be long.
                let mut list = names.iter().take(24).cloned().collect::<Vec<_>>().join(", ");
                if names.len() > 24 {
                    list.push_str(&format!(", … {} more", names.len() - 24));
                }
                return Err(Error::config(format!(
                    "{}: {why}; name the joints in the config, e.g. \"roles\": {{\"{}\": \"<joint name>\"}}; joints: [{list}]",
                    source.name,
                    role.name()
                )));
            }
        }
        let pairs = roles::mirror_pairs(&names, &parents, humanoid.as_ref().ok());
        let animated_translation = bvh
            .joints
            .iter()
            .map(|j| j.channels.iter().any(|c| matches!(c, Channel::PosX | Channel::PosY | Channel::PosZ)))
            .collect();
        Ok(Reference { names, parents, roles, pairs, animated_translation })
    }

    pub fn num_joints(&self) -> usize {
        self.names.len()
    }

    /// Rest positions (identity rotations) from `offsets`, by the one FK.
    pub fn rest_positions(&self, offsets: &[DVec3]) -> Vec<DVec3> {
        let n = offsets.len();
        let (mut p, mut r) = (vec![DVec3::ZERO; n], vec![DQuat::IDENTITY; n]);
        local_to_model(&self.parents, 0..n, None, offsets, &vec![DQuat::IDENTITY; n], &mut p, &mut r);
        p
    }

    /// Rest length of the legs (upper leg → foot, mean of both sides).
    pub fn leg_length(&self, offsets: &[DVec3]) -> f64 {
        let chain = |upper: usize, foot: usize| {
            let (mut j, mut length) = (foot, 0.0);
            while j != upper {
                length += offsets[j].length();
                match self.parents[j] {
                    p if p >= 0 => j = p as usize,
                    _ => break,
                }
            }
            length
        };
        let r = &self.roles;
        0.5 * (chain(r[Role::LeftUpperLeg], r[Role::LeftFoot]) + chain(r[Role::RightUpperLeg], r[Role::RightFoot]))
    }

    /// Forward in the hips' rest frame: left-to-right hip axis × up (left = +X when facing +Z).
    pub fn forward_rest(&self, offsets: &[DVec3]) -> DVec3 {
        let rest = self.rest_positions(offsets);
        (rest[self.roles[Role::LeftUpperLeg]] - rest[self.roles[Role::RightUpperLeg]])
            .cross(DVec3::Y)
            .try_normalize()
            .unwrap_or(DVec3::Z)
    }

    /// The `.mmdb` skeleton: the virtual root as joint 0, the BVH joints under it with
    /// `offsets` (metres, Y up), and one site per role. A missing toe joint (e.g. CMU Daz) is
    /// the foot's end site, scaled and turned like the offsets (`scale`, `up`).
    pub fn database_skeleton(&self, offsets: &[DVec3], bvh: &Bvh, scale: f64, up: DQuat) -> Skeleton {
        let mut skeleton = Skeleton {
            names: std::iter::once(VIRTUAL_ROOT.to_string()).chain(self.names.iter().cloned()).collect(),
            parents: std::iter::once(-1).chain(self.parents.iter().map(|&p| if p < 0 { 0 } else { p + 1 })).collect(),
            offsets: std::iter::once(Vec3::ZERO).chain(offsets.iter().map(|o| o.as_vec3())).collect(),
            sites: Vec::new(),
            mirror: std::iter::once(0).chain(self.pairs.iter().map(|&k| k + 1)).collect(),
        };
        for role in Role::ALL {
            let (joint, offset) = match (self.roles.get(role), role) {
                (Some(j), _) => (j as i32 + 1, Vec3::ZERO),
                (None, Role::LeftToe | Role::RightToe) => {
                    let foot = self.roles[if role == Role::LeftToe { Role::LeftFoot } else { Role::RightFoot }];
                    let end = bvh.joints[foot].end_site.map_or(DVec3::ZERO, |e| up * e * scale);
                    (foot as i32 + 1, end.as_vec3())
                }
                (None, _) => (-1, Vec3::ZERO),
            };
            skeleton.sites.push(Site { name: role.name().to_string(), joint, offset });
        }
        skeleton
    }
}

/// Whether `source` has the reference's skeleton topology (names and parents, joint by joint).
/// Takes that do not are retargeted onto it (`super::retarget`).
pub fn same_topology(reference: &Source, source: &Source) -> bool {
    let (a, b) = (&reference.bvh.joints, &source.bvh.joints);
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.name == y.name && x.parent == y.parent)
}
