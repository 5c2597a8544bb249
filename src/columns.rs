//! Column names shared by several tables, each spelled here and nowhere else: the studies write them
//! (`output::table`), and the readers of points and measurement files and of the studies' own output
//! (`model::grid`, `diagnose::data`, `plot`) look for them. A map's output is therefore a valid points file.

/// Row number in input order, from 0.
pub const INDEX: &str = "index";
/// The point's name, where the input gives one.
pub const NAME: &str = "name";
/// The tip of a tree a row is at (a model with several tips).
pub const TIP: &str = "tip";
/// Commanded position of the platform's reference point.
pub const POSITION: [&str; 3] = ["x_mm", "y_mm", "z_mm"];
/// Commanded orientation, a rotation vector.
pub const ORIENTATION: [&str; 3] = ["pose_rx_rad", "pose_ry_rad", "pose_rz_rad"];
/// A small displacement of the reference point: translation, then rotation vector.
pub const DISPLACEMENT: [&str; 6] = ["dx_mm", "dy_mm", "dz_mm", "rx_rad", "ry_rad", "rz_rad"];
/// A wrench at the reference point.
pub const WRENCH: [&str; 6] = ["Fx_N", "Fy_N", "Fz_N", "Mx_Nmm", "My_Nmm", "Mz_Nmm"];
/// The outcome of a point or row (docs/GUIDE.md lists the statuses).
pub const STATUS: &str = "status";
/// Maps: the largest principal translational compliance (the default column of a map's picture).
pub const C_TRAN_MAX: &str = "c_tran_max_mm_per_N";
/// Newton iterations.
pub const ITERATIONS: &str = "iterations";
/// Curves: the load factor of a row (marks a curve for `stiff plot`).
pub const LOAD_FACTOR: &str = "load_factor";
/// Curves: whether the row's equilibrium is stable.
pub const STABLE: &str = "stable";
/// Curves: events at a row.
pub const EVENT: &str = "event";
/// Assembly: the prefix of the non-linear assembly's displacement (marks an assembly for `stiff plot`).
pub const NONLINEAR: &str = "nl";
/// The prefix of a points file's or a measurement file's joint-coordinate columns: `q_<joint name>` (rad,
/// or mm for a prismatic joint).
pub const JOINT_PREFIX: &str = "q_";
/// Measurements: the pose a row belongs to.
pub const POSE_ID: &str = "pose_id";
/// Measurements: the standard deviation of a measured coordinate.
pub const SIGMA: &str = "sigma_mm";
/// A measurement's place in the order it was taken (a count or a time in any unit), for the drift effect;
/// `time` is read as its other name.
pub const ORDER: &str = "order";
/// Compensation: how the command was computed (`newton`, `mirror`).
pub const METHOD: &str = "method";
/// Compensation: the commanded pose given to the nominal inverse kinematics (marks a compensation table).
pub const COMMAND: [&str; 6] =
    ["command_x_mm", "command_y_mm", "command_z_mm", "command_rx_rad", "command_ry_rad", "command_rz_rad"];
/// Compensation: the prefix of the error with the target as the command.
pub const UNCOMPENSATED: &str = "uncompensated";
/// Compensation: the prefix of the error with the mirror command.
pub const MIRROR: &str = "mirror";
/// Compensation: the prefix of the error with the command written, from an independent forward solve.
pub const RESIDUAL: &str = "residual";
