//! Appearance profiles (`hdlod-appearance/1`, schemas/appearance.schema.json,
//! docs/formats.md): how an element looks while its task has not started,
//! runs or has finished, and while it runs early or late against the plan,
//! per task type. The idea is Navisworks TimeLiner's appearance
//! definitions (start, end, early and late appearances per task type);
//! the defaults follow its spirit: work under construction green and half
//! transparent, then the model's own colour; demolition red, then gone;
//! temporary works yellow, then gone.
//!
//! A look can only recolour, make transparent or hide an element that is
//! present: when it is present is the tree's business (its schedule, as
//! built).

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::status::{Deviation, Progress};
use super::{NamedType, TaskType};
use crate::error::{Error, Result};

/// The value of the `format` field.
pub const FORMAT: &str = "hdlod-appearance/1";

/// How an element looks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Look {
    /// Its own colour.
    Model,
    Hidden,
    /// A colour (sRGB bytes) with a transparency from 0 (opaque) to 1.
    Colour {
        rgb: [u8; 3],
        transparency: f32,
    },
}

/// The looks of one task type, by phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TypeLooks {
    pub before: Look,
    pub active: Look,
    pub after: Look,
    /// While the task runs ahead of its plan; `None` keeps the phase's look.
    pub early: Option<Look>,
    /// While it runs behind its plan; `None` keeps the phase's look.
    pub late: Option<Look>,
}

/// A whole profile: the looks of each task type, and of the IFC task types
/// it names apart.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    pub name: String,
    /// Indexed by [`TaskType::index`].
    pub types: [TypeLooks; 4],
    /// By IFC name (`INSTALLATION`): for tasks of that IFC type, in place
    /// of their type's looks.
    pub ifc: BTreeMap<&'static str, TypeLooks>,
}

impl Default for Profile {
    fn default() -> Self {
        let colour = |hex: u32, transparency: f32| Look::Colour {
            rgb: [(hex >> 16) as u8, (hex >> 8) as u8, hex as u8],
            transparency,
        };
        let looks = |active: Look, after: Look| TypeLooks {
            before: Look::Model,
            active,
            after,
            early: None,
            late: None,
        };
        Profile {
            name: "default".into(),
            types: [
                looks(colour(0x2fb344, 0.5), Look::Model),
                looks(colour(0xd93025, 0.0), Look::Hidden),
                looks(colour(0xf2c21b, 0.0), Look::Hidden),
                looks(Look::Model, Look::Model),
            ],
            ifc: BTreeMap::new(),
        }
    }
}

impl Profile {
    /// The look of an element under a task of type `kind` at `progress`,
    /// `deviation` being the task's against its plan, when it has actual
    /// dates.
    pub fn look(
        &self,
        kind: impl Into<NamedType>,
        progress: Progress,
        deviation: Option<Deviation>,
    ) -> Look {
        let kind = kind.into();
        let looks = kind
            .ifc
            .and_then(|name| self.ifc.get(name))
            .unwrap_or(&self.types[kind.kind.index()]);
        let special = match deviation {
            Some(Deviation::Early) => looks.early,
            Some(Deviation::Late) => looks.late,
            _ => None,
        };
        special.unwrap_or(match progress {
            Progress::NotStarted => looks.before,
            Progress::Active => looks.active,
            Progress::Finished => looks.after,
        })
    }

    /// Reads a profile file; errors name the file and the field.
    pub fn load(path: &Path) -> Result<Profile> {
        let text = crate::input::read_to_string(path)?;
        let de = &mut serde_json::Deserializer::from_str(&text);
        let file: ProfileFile = serde_path_to_error::deserialize(de)
            .map_err(|e| Error::invalid(path, e.path().to_string(), e.into_inner().to_string()))?;
        Profile::from_file(file, path, "")
    }

    /// A parsed profile checked; `at` prefixes the fields in errors (the
    /// profile may sit inside another file).
    pub fn from_file(f: ProfileFile, file: &Path, at: &str) -> Result<Profile> {
        let err =
            |field: String, message: String| Error::invalid(file, format!("{at}{field}"), message);
        if f.format != FORMAT {
            return Err(err(
                "format".into(),
                format!("{:?} is not supported (expected {FORMAT:?})", f.format),
            ));
        }
        // Our types first: an IFC type's phases left out are its type's.
        let mut keys: Vec<(&String, &TypeFile, NamedType)> = Vec::new();
        for (key, entry) in &f.types {
            let named = NamedType::parse(key).ok_or_else(|| {
                err(
                    format!("types.{key}"),
                    format!("{key:?} is not a task type; use {}", TaskType::NAMES),
                )
            })?;
            if let Some((first, ..)) = keys.iter().find(|(_, _, n)| *n == named) {
                return Err(err(
                    format!("types.{key}"),
                    format!("names the same task type as types.{first}"),
                ));
            }
            keys.push((key, entry, named));
        }
        keys.sort_by_key(|(_, _, named)| named.ifc.is_some());
        let mut types = Profile::default().types;
        let mut ifc = BTreeMap::new();
        for (key, entry, named) in keys {
            let field = |phase: &str| format!("types.{key}.{phase}");
            let phase = |e: &Option<EntryFile>, name: &str| -> Result<Option<Look>> {
                e.as_ref()
                    .map(|e| e.look().map_err(|m| err(field(name), m)))
                    .transpose()
            };
            let (before, active, after, early, late) = (
                phase(&entry.before, "before")?,
                phase(&entry.active, "active")?,
                phase(&entry.after, "after")?,
                phase(&entry.early, "early")?,
                phase(&entry.late, "late")?,
            );
            let kind = &mut types[named.kind.index()];
            match named.ifc {
                // A type named with no phase at all keeps the defaults: `{}`
                // is "as usual", not "plain".
                None if !entry.is_empty() => {
                    *kind = TypeLooks {
                        before: before.unwrap_or(Look::Model),
                        active: active.unwrap_or(Look::Model),
                        after: after.unwrap_or(Look::Model),
                        early,
                        late,
                    }
                }
                None => {}
                Some(name) => {
                    ifc.insert(
                        name,
                        TypeLooks {
                            before: before.unwrap_or(kind.before),
                            active: active.unwrap_or(kind.active),
                            after: after.unwrap_or(kind.after),
                            early: early.or(kind.early),
                            late: late.or(kind.late),
                        },
                    );
                }
            }
        }
        Ok(Profile {
            name: f.name.unwrap_or_else(|| "unnamed".into()),
            types,
            ifc,
        })
    }

    /// The file form, every type and phase spelled out.
    pub fn to_file(&self) -> ProfileFile {
        let entry = |l: Look| Some(EntryFile::of(l));
        ProfileFile {
            format: FORMAT.into(),
            name: Some(self.name.clone()),
            types: TaskType::ALL
                .iter()
                .map(|&k| (k.name(), &self.types[k.index()]))
                .chain(self.ifc.iter().map(|(&name, t)| (name, t)))
                .map(|(name, t)| {
                    (
                        name.to_string(),
                        TypeFile {
                            before: entry(t.before),
                            active: entry(t.active),
                            after: entry(t.after),
                            early: t.early.map(EntryFile::of),
                            late: t.late.map(EntryFile::of),
                        },
                    )
                })
                .collect(),
        }
    }
}

/// The file form of a profile.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileFile {
    pub format: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Keyed by task type: ours or an IFC name (`TaskType::parse`).
    #[serde(default)]
    pub types: BTreeMap<String, TypeFile>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TypeFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub before: Option<EntryFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub active: Option<EntryFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub after: Option<EntryFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub early: Option<EntryFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub late: Option<EntryFile>,
}

impl TypeFile {
    fn is_empty(&self) -> bool {
        [
            &self.before,
            &self.active,
            &self.after,
            &self.early,
            &self.late,
        ]
        .iter()
        .all(|e| e.is_none())
    }
}

/// `"model"`, `"hidden"`, or `{"color": "#rrggbb", "transparency": 0.5}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum EntryFile {
    Keyword(String),
    Colour {
        color: String,
        #[serde(default, skip_serializing_if = "is_zero")]
        transparency: f32,
    },
}

fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

impl EntryFile {
    fn look(&self) -> std::result::Result<Look, String> {
        match self {
            EntryFile::Keyword(k) => match k.as_str() {
                "model" => Ok(Look::Model),
                "hidden" => Ok(Look::Hidden),
                other => Err(format!(
                    "{other:?} is not a look; use \"model\", \"hidden\" or {{\"color\": \"#rrggbb\", \"transparency\": 0..1}}"
                )),
            },
            EntryFile::Colour {
                color,
                transparency,
            } => {
                let hex = color
                    .strip_prefix('#')
                    .filter(|h| h.len() == 6)
                    .and_then(|h| u32::from_str_radix(h, 16).ok())
                    .ok_or_else(|| format!("color {color:?} is not of the form \"#rrggbb\""))?;
                if !(0.0..=1.0).contains(transparency) {
                    return Err(format!("transparency {transparency} is not within 0..1"));
                }
                Ok(Look::Colour {
                    rgb: [(hex >> 16) as u8, (hex >> 8) as u8, hex as u8],
                    transparency: *transparency,
                })
            }
        }
    }

    fn of(look: Look) -> EntryFile {
        match look {
            Look::Model => EntryFile::Keyword("model".into()),
            Look::Hidden => EntryFile::Keyword("hidden".into()),
            Look::Colour { rgb, transparency } => EntryFile::Colour {
                color: format!("#{:02x}{:02x}{:02x}", rgb[0], rgb[1], rgb[2]),
                transparency,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(json: &str) -> Result<Profile> {
        let f: ProfileFile = serde_json::from_str(json).unwrap();
        Profile::from_file(f, Path::new("p.json"), "")
    }

    #[test]
    fn the_defaults_follow_timeliner() {
        let p = Profile::default();
        let green = p.look(TaskType::Construct, Progress::Active, None);
        assert!(
            matches!(green, Look::Colour { rgb, transparency } if rgb[1] > rgb[0] && transparency == 0.5)
        );
        assert_eq!(
            p.look(TaskType::Construct, Progress::Finished, None),
            Look::Model
        );
        assert_eq!(
            p.look(TaskType::Demolish, Progress::Finished, None),
            Look::Hidden
        );
        assert_eq!(
            p.look(TaskType::Temporary, Progress::Finished, None),
            Look::Hidden
        );
    }

    #[test]
    fn a_profile_round_trips_and_late_overrides_the_phase() {
        let p = parse(
            r##"{"format": "hdlod-appearance/1", "name": "late red",
                 "types": {"construct": {"active": {"color": "#0000ff", "transparency": 0.25},
                                         "late": {"color": "#ff0000"}},
                           "demolish": {}}}"##,
        )
        .unwrap();
        let late = p.look(TaskType::Construct, Progress::Active, Some(Deviation::Late));
        assert_eq!(
            late,
            Look::Colour {
                rgb: [255, 0, 0],
                transparency: 0.0
            }
        );
        let on_time = p.look(
            TaskType::Construct,
            Progress::Active,
            Some(Deviation::OnTime),
        );
        assert_eq!(
            on_time,
            Look::Colour {
                rgb: [0, 0, 255],
                transparency: 0.25
            }
        );
        // An empty type keeps the defaults.
        assert_eq!(p.types[1], Profile::default().types[1]);
        let again = Profile::from_file(p.to_file(), Path::new("p.json"), "").unwrap();
        assert_eq!(again, p);
    }

    #[test]
    fn ifc_task_types_of_one_type_look_apart() {
        let p = parse(
            r##"{"format": "hdlod-appearance/1",
                 "types": {"construct": {"active": {"color": "#00ff00"}, "late": {"color": "#ff0000"}},
                           "installation": {"active": {"color": "#0000ff"}}}}"##,
        )
        .unwrap();
        let named = |name: &str| NamedType::parse(name).unwrap();
        let blue = Look::Colour {
            rgb: [0, 0, 255],
            transparency: 0.0,
        };
        let green = Look::Colour {
            rgb: [0, 255, 0],
            transparency: 0.0,
        };
        assert_eq!(p.look(named("INSTALLATION"), Progress::Active, None), blue);
        // CONSTRUCTION has no entry of its own: construct's looks.
        assert_eq!(p.look(named("CONSTRUCTION"), Progress::Active, None), green);
        assert_eq!(p.look(TaskType::Construct, Progress::Active, None), green);
        // The phases INSTALLATION leaves out are construct's.
        let late = p.look(
            named("INSTALLATION"),
            Progress::Active,
            Some(Deviation::Late),
        );
        assert_eq!(
            late,
            p.look(TaskType::Construct, Progress::Active, Some(Deviation::Late))
        );
        assert_eq!(
            p.look(named("INSTALLATION"), Progress::Finished, None),
            Look::Model
        );
        let again = Profile::from_file(p.to_file(), Path::new("p.json"), "").unwrap();
        assert_eq!(again, p);
        assert!(again.to_file().types.contains_key("INSTALLATION"));
    }

    #[test]
    fn bad_profiles_name_the_field() {
        let e = parse(r#"{"format": "hdlod-appearance/1", "types": {"paint": {}}}"#).unwrap_err();
        assert!(e.to_string().contains("types.paint"), "{e}");
        let e =
            parse(r#"{"format": "hdlod-appearance/1", "types": {"construct": {"after": "gone"}}}"#)
                .unwrap_err();
        assert!(e.to_string().contains("types.construct.after"), "{e}");
        let e = parse(
            r#"{"format": "hdlod-appearance/1", "types": {"construct": {"active": {"color": "green"}}}}"#,
        )
        .unwrap_err();
        assert!(e.to_string().contains("#rrggbb"), "{e}");
        let e = parse(
            r#"{"format": "hdlod-appearance/1", "types": {"INSTALLATION": {}, "installation": {}}}"#,
        )
        .unwrap_err();
        assert!(e.to_string().contains("same task type"), "{e}");
    }
}
