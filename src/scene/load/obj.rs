//! OBJ meshes and the MTL materials they name.

use super::*;

/// One OBJ file with its models and MTL materials.
pub(super) struct ObjFile {
    pub(super) path: PathBuf,
    pub(super) models: Vec<tobj::Model>,
    pub(super) materials: Vec<tobj::Material>,
    /// The MTL file each material came from, for messages about it.
    pub(super) mtl_files: HashMap<String, PathBuf>,
}

impl ObjFile {
    /// A missing MTL file is a warning (the objects fall back to the
    /// default material); one that does not parse is an error naming it.
    /// The caller has checked that `path` is a regular file.
    pub(super) fn read(path: &Path, warnings: &mut Vec<String>) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read mesh {}", path.display()))?;
        check_obj(path, &text)?;
        let opts = tobj::LoadOptions {
            single_index: true,
            triangulate: true,
            ignore_points: true,
            ignore_lines: true,
        };
        let dir = path.parent().unwrap_or(Path::new("."));
        let mtl_warnings = std::cell::RefCell::new(Vec::new());
        let mtl_error = std::cell::RefCell::new(None);
        let mtl_files = std::cell::RefCell::new(HashMap::new());
        let (models, materials) = tobj::load_obj_buf(&mut text.as_bytes(), &opts, |name| {
            let mtl = dir.join(name);
            let read = match not_a_file(&mtl) {
                Some(why) => Err(why),
                None => std::fs::read_to_string(&mtl).map_err(|e| format!("cannot be read: {e}")),
            };
            let text = match read {
                Ok(text) => text,
                Err(why) => {
                    mtl_warnings.borrow_mut().push(format!(
                        "{}: MTL file {} {why}: its materials fall back to the default",
                        path.display(),
                        mtl.display()
                    ));
                    return Ok(Default::default());
                }
            };
            let (text, w) = match prepare_mtl(&mtl, &text) {
                Ok(prepared) => prepared,
                Err(e) => {
                    *mtl_error.borrow_mut() = Some(e);
                    return Err(tobj::LoadError::MaterialParseError);
                }
            };
            mtl_warnings.borrow_mut().extend(w);
            tobj::load_mtl_buf(&mut text.as_bytes())
                .inspect(|(materials, _)| {
                    let mut files = mtl_files.borrow_mut();
                    for m in materials {
                        files.insert(m.name.clone(), mtl.clone());
                    }
                })
                .inspect_err(|e| {
                    *mtl_error.borrow_mut() =
                        Some(anyhow!("cannot read MTL file {}: {e}", mtl.display()));
                })
        })
        .map_err(|e| anyhow!("cannot read mesh {}: {e}", path.display()))?;
        if let Some(e) = mtl_error.into_inner() {
            return Err(e);
        }
        warnings.extend(mtl_warnings.into_inner());
        // An MTL failure was reported above; none are left here.
        let materials = materials.unwrap_or_default();
        Ok(Self {
            path: path.to_path_buf(),
            models,
            materials,
            mtl_files: mtl_files.into_inner(),
        })
    }

    /// The triangles of `group` (or all groups) with zero-area triangles
    /// dropped and counted, and the MTL material name the group uses.
    pub(super) fn mesh(&self, group: Option<&str>) -> Result<(Mesh, Option<String>, usize)> {
        let models: Vec<&tobj::Model> = match group {
            Some(g) => self.models.iter().filter(|m| m.name == g).collect(),
            None => self.models.iter().collect(),
        };
        if models.is_empty() {
            let names: Vec<&str> = self.models.iter().map(|m| m.name.as_str()).collect();
            bail!(
                "{}: no group `{}` in the mesh (groups: {})",
                self.path.display(),
                group.unwrap_or("*"),
                names.join(", ")
            );
        }
        let mut mesh = Mesh::default();
        let with_uvs = models.iter().all(|m| !m.mesh.texcoords.is_empty());
        let mut uvs = Vec::new();
        let mut dropped = 0;
        let mut mtl = None;
        for m in models {
            let base = mesh.positions.len() as u32;
            let p = &m.mesh.positions;
            ensure!(
                p.iter().all(|c| c.is_finite()),
                "{}: group `{}` has a vertex coordinate that is not finite",
                self.path.display(),
                m.name
            );
            if let Some(c) = p.iter().find(|c| c.abs() > crate::scene::MAX_COORDINATE) {
                bail!(
                    "{}: group `{}` has a vertex coordinate {c:e} beyond ±{:e}, the farthest a coordinate may reach (so that distances between points stay finite): scale the mesh down",
                    self.path.display(),
                    m.name,
                    crate::scene::MAX_COORDINATE
                );
            }
            mesh.positions
                .extend(p.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])));
            if with_uvs {
                uvs.extend(
                    m.mesh
                        .texcoords
                        .chunks_exact(2)
                        .map(|c| Vec2::new(c[0], c[1])),
                );
            }
            for t in m.mesh.indices.chunks_exact(3) {
                let tri = [base + t[0], base + t[1], base + t[2]];
                if mesh.triangle_area(tri) > 0.0 {
                    mesh.triangles.push(tri);
                } else {
                    dropped += 1;
                }
            }
            if mtl.is_none() {
                mtl = m
                    .mesh
                    .material_id
                    .and_then(|i| self.materials.get(i))
                    .map(|x| x.name.clone());
            }
        }
        mesh.uvs = with_uvs.then_some(uvs);
        Ok((mesh, mtl, dropped))
    }
}
