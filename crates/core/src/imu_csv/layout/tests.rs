use super::*;

const XSENS: &str = "// Start Time: 0\n// Sample rate: 50.0Hz\n// Scenario: 4.9\n\
Counter\tAcc_X\tAcc_Y\tAcc_Z\tGyr_X\tGyr_Y\tGyr_Z\tMag_X\tMag_Y\tMag_Z\tQuat_w\tQuat_x\tQuat_y\tQuat_z\n\
 65534\t4.374240\t8.578849\t-1.814515\t0.059158\t-0.030138\t0.050860\t-0.484053\t-1.107940\t0.265724\t0.567189\t0.769786\t0.003829\t0.292765\t\n\
 65535\t4.474578\t8.604048\t-1.819616\t0.032979\t-0.008316\t0.031548\t-0.484605\t-1.108990\t0.267544\t0.566843\t0.769998\t0.003635\t0.292879\t\n\
 0\t4.374881\t8.540353\t-1.805151\t0.022677\t0.009977\t0.018773\t-0.485015\t-1.109239\t0.266979\t0.566614\t0.770098\t0.003613\t0.293061\t\n\
 1\t4.374881\t8.540353\t-1.805151\t0.022677\t0.009977\t0.018773\t-0.485015\t-1.109239\t0.266979\t0.566614\t0.770098\t0.003613\t0.293061\t\n";

#[test]
fn an_xsens_export_reads_as_it_comes() {
    let r = read(XSENS, "x.txt", &ReadOptions::default()).unwrap();
    let rec = &r.recording;
    assert_eq!(rec.t.len(), 4);
    // The counter wraps at 2¹⁶ and runs at the comment's 50 Hz.
    assert!((r.rate_hz - 50.0).abs() < 1e-9, "{}", r.rate_hz);
    assert!((rec.t[3] - rec.t[0] - 0.06).abs() < 1e-9);
    assert_eq!(rec.accel[0], Vector3::new(4.374240, 8.578849, -1.814515));
    assert_eq!(rec.gyro[1][2], 0.031548);
    assert!(rec.mag.is_some() && rec.euler.is_none());
    let q = rec.quat.as_ref().unwrap()[0];
    let given: Vector4<f64> = Vector4::new(0.567189, 0.769786, 0.003829, 0.292765);
    assert!((q - given / given.norm()).norm() < 1e-12);
    assert!(r.notes.iter().any(|n| n == "delimiter: tab"));
    assert!(r.notes.iter().any(|n| n.starts_with("accelerometer: m/s²")));
    assert_eq!(r.columns[0], ("t".to_string(), "Counter".to_string()));
}

#[test]
fn units_in_the_header_are_applied() {
    let text = "Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),Accelerometer X (g),\
Accelerometer Y (g),Accelerometer Z (g),Magnetometer X (uT),Magnetometer Y (uT),Magnetometer Z (uT)\n\
0.00,180,0,0,0,0,1,20,-8,-44\n0.02,0,90,0,0,0,1,20,-8,-44\n0.04,0,0,-45,0,0.5,1,20,-8,-44\n";
    let r = read(text, "ngimu.csv", &ReadOptions::default()).unwrap();
    let rec = &r.recording;
    let pi = std::f64::consts::PI;
    assert!((rec.gyro[0][0] - pi).abs() < 1e-12 && (rec.gyro[2][2] + pi / 4.0).abs() < 1e-12);
    assert!((rec.accel[0][2] - G0).abs() < 1e-12 && (rec.accel[2][1] - G0 / 2.0).abs() < 1e-12);
    assert_eq!(rec.mag.as_ref().unwrap()[0], Vector3::new(20.0, -8.0, -44.0));
    assert!((r.rate_hz - 50.0).abs() < 1e-6);
    // Microseconds.
    let us = "Timestamp (us),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),Accelerometer X (g),\
Accelerometer Y (g),Accelerometer Z (g)\n1000000,0,0,0,0,0,1\n1010000,0,0,0,0,0,1\n1020000,0,0,0,0,0,1\n";
    let r = read(us, "xio.csv", &ReadOptions::default()).unwrap();
    assert!((r.rate_hz - 100.0).abs() < 1e-6 && (r.recording.t[0] - 1.0).abs() < 1e-12);
}

/// m/s² declared as g would read as ten times gravity: refused, saying so.
#[test]
fn an_accelerometer_in_m_s2_declared_as_g_is_refused() {
    let text = "t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.01,0,0,9.8,0,0,0\n0.02,0,0.1,9.8,0,0,0\n";
    let o = ReadOptions {
        units: parse_units("accel=g").unwrap(),
        ..Default::default()
    };
    let e = read(text, "x.csv", &o).unwrap_err().to_string();
    assert!(e.contains("96.") && e.contains("accel=m/s2"), "{e}");
    // In g, the same file with values near 1 reads.
    let g = text.replace("9.8", "1.0");
    assert!(read(&g, "x.csv", &o).is_ok());
}

#[test]
fn a_mapping_names_columns_the_usual_names_miss() {
    let text = "% logger v2\nn;A1;A2;A3;W1;W2;W3;R;P;Y\n0;0;0;1;0;0;0;10;0;90\n1;0;0;1;0;0;0;10;0;90\n\
2;0;0;1;0;0;0;10;0;-90\n";
    let o = ReadOptions {
        columns: parse_columns("t=n/200,ax=A1,ay=A2,az=A3,gx=W1,gy=W2,gz=W3,roll=R,pitch=P,yaw=Y").unwrap(),
        units: Units {
            gyro: unit_factor("gyro", "deg/s"),
            ..Default::default()
        },
        ..Default::default()
    };
    let r = read(text, "log.csv", &o).unwrap();
    assert!((r.rate_hz - 200.0).abs() < 1e-9);
    let e = r.recording.euler.as_ref().unwrap();
    assert!(
        (e[0][2] - std::f64::consts::FRAC_PI_2).abs() < 1e-12,
        "degrees detected: {e:?}"
    );
    assert!(
        r.notes
            .iter()
            .any(|n| n.starts_with("accelerometer: g (from the median |a| = 1.000")),
        "{:?}",
        r.notes
    );
    assert!(r.notes.iter().any(|n| n == "delimiter: semicolon"));
}

#[test]
fn errors_name_the_file_line_and_column() {
    let bad = |text: &str, o: &ReadOptions, line: usize, says: &str| {
        let e = read(text, "f.txt", o).unwrap_err();
        assert_eq!((e.file.as_str(), e.line), ("f.txt", line), "{e}");
        assert!(e.message.contains(says), "{e}");
    };
    let d = ReadOptions::default();
    bad("", &d, 1, "empty");
    bad("# only\n", &d, 1, "empty");
    bad("t,foo,bar\n0,1,2\n", &d, 1, "no accelerometer");
    bad("t,ax,ay,gx,gy,gz\n", &d, 1, "lacks az");
    bad(
        "t,ax,ay,az,gx,gy,gz\n0,0,0,1,0,0,0\n0.1,0,0,x,0,0,0\n",
        &d,
        3,
        "`x` in column `az`",
    );
    bad("t,ax,ay,az,gx,gy,gz\n0,0,0,1,0,0,0\n0.1,0,0,1,0,0\n", &d, 3, "6 fields");
    bad(
        "t,ax,ay,az,gx,gy,gz\n0,0,0,1,0,0,0\n0,0,0,1,0,0,0\n0.1,0,0,1,0,0,0\n",
        &d,
        3,
        "does not increase",
    );
    bad(
        "Counter,ax,ay,az,gx,gy,gz\n0,0,0,1,0,0,0\n1,0,0,1,0,0,0\n2,0,0,1,0,0,0\n",
        &d,
        1,
        "--rate",
    );
    bad(
        "Time (fortnights),ax,ay,az,gx,gy,gz\n0,0,0,1,0,0,0\n",
        &d,
        1,
        "unknown time unit `fortnights`",
    );
    bad(
        "t,Acc_X (furlongs),Acc_Y (furlongs),Acc_Z (furlongs),gx,gy,gz\n",
        &d,
        1,
        "unknown accel unit `furlongs`",
    );
    let map = ReadOptions {
        columns: parse_columns("ax=Nope").unwrap(),
        ..Default::default()
    };
    bad("t,ax,ay,az,gx,gy,gz\n", &map, 1, "no column `Nope`");
    assert!(parse_columns("ax").is_err() && parse_columns("speed=V").is_err());
}
