//! Bakes the build-time node config (`HOPLOC_*` variables, see `loc_proto::config::from_env`)
//! into the firmware: `$OUT_DIR/config.rs`, included by main.rs.
fn main() {
    loc_proto::build::firmware_config(loc_proto::Role::Anchor);
}
