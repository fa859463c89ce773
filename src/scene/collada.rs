//! COLLADA 1.4.1 + CGL loader (TEMPORARY stub until the loader branch lands).
use super::Scene;
use std::path::Path;

pub fn load(path: &Path) -> crate::Result<Scene> {
    crate::bail!("{}: loader not yet available", path.display())
}
