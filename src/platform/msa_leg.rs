//! A leg described by matrix structural analysis (paper 003): its geometry follows the pose through the
//! template's formulas, and its answer is the end node's stiffness (eq 17) and the wrench its preloads exert,
//! moved to the platform's reference point. The model is linear: at a platform displaced from where the leg
//! was placed, the wrench changes by the placed stiffness times the displacement, so the loaded studies run
//! on MSA legs as on VJM ones, without large-deflection effects inside the leg.

use super::leg::{at_reference_point, LegFailure, LegResponse};
use crate::kinematics::frame::Frame;
use crate::msa::template::{PoseOutOfReach, Template};
use crate::msa::{Condenser, MsaFailure, Structure};

/// An MSA leg: a structure evaluated at each pose (paper 003), answered through the leg seam.
#[derive(Clone, Debug)]
pub struct MsaLeg {
    /// The leg's name.
    pub name: String,
    /// Its structure as formulas of the pose.
    pub template: Template,
    /// The copy's frame: the template's leg frame in the base frame.
    pub place: Frame,
    /// The leg's end frame in the platform frame (copy included).
    pub attachment: Frame,
    /// mm per rad, to weigh rotations against translations.
    pub length_scale: f64,
}

/// What an MSA leg keeps between calls: the answer at its placement (for the linear loaded answer), and
/// the buffers of its evaluation (the formulas' value table, the structure, its condenser), so a map
/// allocates nothing per pose.
#[derive(Clone, Debug, Default)]
pub struct MsaState {
    /// The formulas' value table.
    pub slots: Vec<f64>,
    /// The structure at the last pose evaluated.
    pub structure: Structure,
    /// The solver of the structure, its forest and buffers made at the first pose.
    pub condenser: Condenser,
    /// Platform pose at placement, and the leg's answer there.
    pub placed: Option<(Frame, LegResponse)>,
}

impl MsaLeg {
    /// The structure (base frame) with the platform at `platform`.
    pub fn structure_at(&self, platform: &Frame) -> Result<Structure, LegFailure> {
        let mut structure = Structure::default();
        self.fill(platform, &mut Vec::new(), &mut structure)?;
        Ok(structure)
    }

    fn fill(&self, platform: &Frame, slots: &mut Vec<f64>, structure: &mut Structure) -> Result<(), LegFailure> {
        let target = platform.compose(&self.attachment);
        let local = self.place.inverse().compose(&target);
        self.template.fill(&local, &self.place, slots, structure).map_err(|e| match e {
            PoseOutOfReach::Condition(k) => LegFailure::OutOfReach { condition: Some(k) },
            PoseOutOfReach::NotFinite => LegFailure::OutOfReach { condition: None },
            PoseOutOfReach::Degenerate => LegFailure::NotFinite,
        })
    }

    /// The leg's answer with the platform at `platform`, its geometry evaluated there.
    fn answer(&self, platform: &Frame, state: &mut MsaState) -> Result<LegResponse, LegFailure> {
        self.fill(platform, &mut state.slots, &mut state.structure)?;
        let structure = &state.structure;
        let end = state.condenser.condense(structure).map_err(|e| match e {
            MsaFailure::Mechanism { .. } | MsaFailure::BadNode(_) => LegFailure::SingularChain,
            MsaFailure::NotFinite => LegFailure::NotFinite,
        })?;
        let v = structure.nodes[structure.end] - platform.pos;
        // The holding wrench is what the platform applies to the leg's end; the leg exerts its opposite.
        let at_rp = at_reference_point(&end.holding_wrench, &end.stiffness, &v);
        Ok(LegResponse {
            wrench: -at_rp.wrench,
            stiffness: at_rp.stiffness,
            magnitude: at_rp.magnitude,
            stable: true,
            iterations: 0,
        })
    }

    /// Places the leg: evaluates it at the commanded pose and keeps the answer.
    pub fn place(&self, platform: &Frame, state: &mut MsaState) -> Result<LegResponse, LegFailure> {
        state.placed = None;
        let r = self.answer(platform, state)?;
        state.placed = Some((*platform, r));
        Ok(r)
    }

    /// The linear answer at a platform displaced from the placement: w = w0 - K dt.
    pub fn respond(&self, platform: &Frame, state: &MsaState) -> Result<LegResponse, LegFailure> {
        let (placed, r) = state.placed.as_ref().ok_or(LegFailure::SingularChain)?;
        let d = placed.error_to(platform);
        Ok(LegResponse { wrench: r.wrench - r.stiffness * d, ..*r })
    }
}
