//! The workspace-level integration tests, one module per subject (see
//! ARCHITECTURE.md's test table), linked into one binary.

mod architecture;
mod assets;
mod cme;
mod cme_fit;
mod cme_greedy;
mod cme_kinetics;
mod cme_tt;
mod cme_views;
mod dsmts;
mod evaluation;
mod extremes;
mod fe_convergence;
mod fe_liver;
mod fe_nodule;
mod meta_model_file;
mod nodal_liver;
mod nodule_table;
mod nodule_tissue;
mod nodule_training;
mod nodule_vademecum;
mod pgd_liver;
mod scene;
mod surface_import;
mod tissue;
mod user_organ;
mod visual;
