//! The user's model and recipe files, read from disk here and parsed by
//! `survey_processing` (which reads no file). A file that cannot be read is a
//! defect of that file, named as the parser names one.

use std::path::Path;
use survey_processing::model::{Model, ModelError};
use survey_tables::recipe::{Recipe, RecipeError};

/// Read and validate a model file.
pub fn read_model(path: &Path) -> Result<Model, ModelError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ModelError {
        source_name: name.clone(),
        line: None,
        message: format!("cannot read the model file: {e}"),
    })?;
    Model::parse(&text, &name)
}

/// Read and validate a recipe file.
pub fn read_recipe(path: &Path) -> Result<Recipe, RecipeError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| RecipeError {
        source_name: name.clone(),
        line: None,
        key: String::new(),
        message: format!("cannot read the recipe file: {e}"),
    })?;
    Recipe::parse(&text, &name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unreadable_file_is_a_defect_of_that_file() {
        let e = read_recipe(Path::new("/nonexistent/r.toml")).unwrap_err();
        assert!(e.to_string().starts_with("/nonexistent/r.toml: cannot read the recipe file"), "{e}");
        let e = read_model(Path::new("/nonexistent/m.toml")).unwrap_err();
        assert!(e.to_string().starts_with("/nonexistent/m.toml: cannot read the model file"), "{e}");
    }

    #[test]
    fn a_read_file_is_parsed_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.toml");
        std::fs::write(&path, "[design]\ngear_ratios = [12]\n\n[[effect]]\nkind = \"noise\"\n").unwrap();
        let e = read_model(&path).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}:4:", path.display())), "{e}");
        std::fs::write(&path, "[design]\ngear_ratios = [12]\n").unwrap();
        assert_eq!(read_model(&path).unwrap().design.gear_ratios, [12.0]);
    }
}
