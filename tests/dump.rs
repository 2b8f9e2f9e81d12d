//! ds_problem_dump: the problem a C code handed to the library, written to a folder,
//! reads back to exactly the same problem and solves to the same answer; an
//! unwritable folder is DS_STATUS_IO_ERROR and leaves the handle usable.

mod common;

use common::{Mesh, Scene};
use dualsplit::internals::ffi::{
    DsMatrix, DsOptions, DsStatus, ds_last_error_message, ds_problem_dump, ds_problem_free,
    ds_problem_new, ds_solve,
};
use dualsplit::mtx::{FrictionData, read_problem};
use dualsplit::{Csc, Friction, Options};
use std::ffi::{CStr, CString};

fn scene() -> Scene {
    let mesh = Mesh::grid2d(6, 3, 2.0, 1.0);
    let mut prescribed = Vec::new();
    for &a in &mesh.top_nodes() {
        prescribed.push((2 * a, 0.004));
        prescribed.push((2 * a + 1, -0.02));
    }
    let f_ext = vec![0.0; mesh.n_dofs()];
    let bottom = mesh.bottom_nodes();
    Scene::build(mesh, 100.0, 0.3, &prescribed, &f_ext, &bottom, |x| {
        0.05 * (x[0] - 1.0).powi(2)
    })
}

fn arrays(a: &Csc) -> (Vec<i32>, Vec<i32>) {
    (
        a.col_ptr.iter().map(|&v| v as i32).collect(),
        a.row_idx.iter().map(|&v| v as i32).collect(),
    )
}

fn view(a: &Csc, p: &[i32], i: &[i32]) -> DsMatrix {
    DsMatrix {
        format: 1,
        index_type: 0,
        base: 0,
        storage: 0,
        nrows: a.nrows as i64,
        ncols: a.ncols as i64,
        nnz: 0,
        p: p.as_ptr().cast(),
        i: i.as_ptr().cast(),
        x: a.values.as_ptr(),
    }
}

#[test]
fn dumped_folder_replays_the_same_problem() {
    let sc = scene();
    let mu = vec![0.3; sc.m()];
    let (kp, ki) = arrays(&sc.k);
    let (np, ni) = arrays(&sc.n);
    let (tp, ti) = arrays(&sc.t);
    let mut h = std::ptr::null_mut();
    // SAFETY: the views point to live arrays matching their fields.
    let s = unsafe {
        ds_problem_new(
            2,
            &view(&sc.k, &kp, &ki),
            &view(&sc.n, &np, &ni),
            &view(&sc.t, &tp, &ti),
            &mut h,
        )
    };
    assert_eq!(s, DsStatus::Ok);
    let dir = std::env::temp_dir().join(format!("dualsplit-dump-{}", std::process::id()));
    let cdir = CString::new(dir.to_str().unwrap()).unwrap();
    // SAFETY: live handle, NUL-terminated path, arrays of n, m, m values.
    let s = unsafe {
        ds_problem_dump(
            h,
            cdir.as_ptr(),
            1,
            sc.f.as_ptr(),
            sc.g.as_ptr(),
            mu.as_ptr(),
        )
    };
    assert_eq!(s, DsStatus::Ok);
    let folder = read_problem(&dir).unwrap();
    assert_eq!(folder.d, 2);
    assert_eq!(folder.k, sc.k);
    assert_eq!(folder.n, sc.n);
    assert_eq!(folder.t, sc.t);
    assert_eq!(folder.f, sc.f);
    assert_eq!(folder.g, sc.g);
    let FrictionData::Coulomb(mu_read) = &folder.friction else {
        panic!("mu.txt expected")
    };
    assert_eq!(mu_read, &mu);
    // The folder reproduces what the handle solves: the handle's own ds_solve and
    // a replay from the folder give the same answer, bit for bit.
    let (mut u_h, mut ln_h, mut lt_h) =
        (vec![0.0; sc.k.nrows], vec![0.0; sc.m()], vec![0.0; sc.m()]);
    let o = DsOptions::default();
    // SAFETY: live handle, arrays of the problem's sizes.
    let s = unsafe {
        ds_solve(
            h,
            &o,
            1,
            sc.f.as_ptr(),
            sc.g.as_ptr(),
            mu.as_ptr(),
            u_h.as_mut_ptr(),
            ln_h.as_mut_ptr(),
            lt_h.as_mut_ptr(),
            std::ptr::null_mut(),
        )
    };
    assert_eq!(s, DsStatus::Ok);
    let mut pb =
        dualsplit::ContactProblem::from_csc(folder.d, folder.k, folder.n, folder.t).unwrap();
    let replay = pb
        .solve(
            &folder.f,
            &folder.g,
            Friction::Coulomb(mu_read),
            &Options::default(),
        )
        .unwrap();
    assert_eq!(u_h, replay.u);
    assert_eq!(ln_h, replay.lambda_n);
    assert_eq!(lt_h, replay.lambda_t);

    // A folder path under a regular file cannot be created: IO_ERROR, handle intact.
    let file = dir.join("K.mtx").join("sub");
    let cfile = CString::new(file.to_str().unwrap()).unwrap();
    // SAFETY: as above.
    let s = unsafe {
        ds_problem_dump(
            h,
            cfile.as_ptr(),
            1,
            sc.f.as_ptr(),
            sc.g.as_ptr(),
            mu.as_ptr(),
        )
    };
    assert_eq!(s, DsStatus::IoError);
    // SAFETY: the message is a NUL-terminated thread-local string.
    let msg = unsafe { CStr::from_ptr(ds_last_error_message()) }
        .to_string_lossy()
        .into_owned();
    assert!(
        msg.contains("ds_problem_dump") && msg.contains("sub"),
        "{msg}"
    );
    // Negative friction is refused before anything is written: a fresh folder is
    // not even created.
    let fresh = dir.with_extension("refused");
    let cfresh = CString::new(fresh.to_str().unwrap()).unwrap();
    let neg = vec![-1.0; sc.m()];
    // SAFETY: as above.
    let s = unsafe {
        ds_problem_dump(
            h,
            cfresh.as_ptr(),
            1,
            sc.f.as_ptr(),
            sc.g.as_ptr(),
            neg.as_ptr(),
        )
    };
    assert_eq!(s, DsStatus::NegativeFriction);
    assert!(!fresh.exists(), "{} was created", fresh.display());
    // SAFETY: as above.
    let s = unsafe {
        ds_problem_dump(
            h,
            std::ptr::null(),
            1,
            sc.f.as_ptr(),
            sc.g.as_ptr(),
            mu.as_ptr(),
        )
    };
    assert_eq!(s, DsStatus::NullPointer);
    // SAFETY: handle from ds_problem_new, freed once.
    unsafe { ds_problem_free(h) };
    std::fs::remove_dir_all(&dir).ok();
}
