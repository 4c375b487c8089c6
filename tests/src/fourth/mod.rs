//! The fourth family of simulated rigs for the gap diagnosis, written from
//! plant.md (sections 1-5 and 12) and interfaces.md (sections 1-2) alone,
//! independently of the diagnosis and of the other families.
//!
//! * [`plant`]: parameters and helpers of the nominal plant (section 3-4);
//! * [`rig`]: the right-hand side with this family's effects hooked in and
//!   the classical RK4 (with no effect: the nominal plant, checked against
//!   the vectors of sections 4.1 and 4.2);
//! * [`effects`]: two physically different forms for each identifier of
//!   section 12 and four defects outside it;
//! * [`sensors`]: realistic sensors of section 5 with an own seeded RNG, and
//!   the sensor-side effects;
//! * [`scenario`]: programmes, `dca_core`'s controllers at the board's 1 ms
//!   tick, the closed loop and the run log;
//! * [`cases`]: the case list with its truth;
//! * [`fifth`]: the fifth family, another case list on the same plant with
//!   its own effect forms (appended to [`effects`]);
//! * [`measure`]: writing a family's logs, running the release `host-sim
//!   gap` on them and tabulating the verdicts.

pub mod cases;
pub mod effects;
pub mod fifth;
pub mod measure;
pub mod plant;
pub mod rig;
pub mod scenario;
pub mod sensors;
