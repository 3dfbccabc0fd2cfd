//! The enumerations of `ES_C_API_Def.h` and `Enum.h` (emScon TPI/SDK V3.6)
//! that this driver sends or reads, with their values as the headers declare
//! them. Every C enum travels as a 32-bit little-endian `int`.

/// `enum ES_DataType`: the `type` field of `PacketHeaderT`.
pub mod data_type {
    /// `ES_DT_Command`: a command (`...CT`) or its answer (`...RT`).
    pub const COMMAND: i32 = 0;
    /// `ES_DT_Error`: `ErrorResponseT`.
    pub const ERROR: i32 = 1;
    /// `ES_DT_SingleMeasResult`: `SingleMeasResultT`.
    pub const SINGLE_MEAS_RESULT: i32 = 2;
    /// `ES_DT_MultiMeasResult`.
    pub const MULTI_MEAS_RESULT: i32 = 3;
    /// `ES_DT_StationaryProbeMeasResult`.
    pub const STATIONARY_PROBE_MEAS_RESULT: i32 = 4;
    /// `ES_DT_ContinuousProbeMeasResult`.
    pub const CONTINUOUS_PROBE_MEAS_RESULT: i32 = 5;
    /// `ES_DT_NivelResult`.
    pub const NIVEL_RESULT: i32 = 6;
    /// `ES_DT_ReflectorPosResult`.
    pub const REFLECTOR_POS_RESULT: i32 = 7;
    /// `ES_DT_SystemStatusChange`: `SystemStatusChangeT`.
    pub const SYSTEM_STATUS_CHANGE: i32 = 8;
    /// `ES_DT_SingleMeasResult2`.
    pub const SINGLE_MEAS_RESULT2: i32 = 9;
    /// `ES_DT_MultiMeasResult2`.
    pub const MULTI_MEAS_RESULT2: i32 = 10;
    /// `ES_DT_ProbePosResult`.
    pub const PROBE_POS_RESULT: i32 = 11;
}

/// `enum ES_Command` (the values used here).
pub mod command {
    /// `ES_C_GetSystemStatus`.
    pub const GET_SYSTEM_STATUS: i32 = 1;
    /// `ES_C_SetUnits`.
    pub const SET_UNITS: i32 = 5;
    /// `ES_C_Initialize`.
    pub const INITIALIZE: i32 = 7;
    /// `ES_C_SetMeasurementMode`.
    pub const SET_MEASUREMENT_MODE: i32 = 24;
    /// `ES_C_SetCoordinateSystemType`.
    pub const SET_COORDINATE_SYSTEM_TYPE: i32 = 26;
    /// `ES_C_SetStationaryModeParams`.
    pub const SET_STATIONARY_MODE_PARAMS: i32 = 28;
    /// `ES_C_SetContinuousTimeModeParams`.
    pub const SET_CONTINUOUS_TIME_MODE_PARAMS: i32 = 30;
    /// `ES_C_StopMeasurement`.
    pub const STOP_MEASUREMENT: i32 = 52;
    /// `ES_C_StartMeasurement`.
    pub const START_MEASUREMENT: i32 = 49;
    /// `ES_C_GoLastMeasuredPoint`.
    pub const GO_LAST_MEASURED_POINT: i32 = 62;
    /// `ES_C_FindReflector`.
    pub const FIND_REFLECTOR: i32 = 63;
    /// `ES_C_GoPosition`: turn the beam to a position (the current
    /// coordinate system's values).
    pub const GO_POSITION: i32 = 55;
    /// `ES_C_Unknown`.
    pub const UNKNOWN: i32 = 64;
    /// `ES_C_GetMeasurementStatusInfo`.
    pub const GET_MEASUREMENT_STATUS_INFO: i32 = 122;
    /// `ES_C_SetStatisticMode`: standard or extended statistics of results.
    pub const SET_STATISTIC_MODE: i32 = 80;

    /// Whether `c` is a value of `enum ES_Command` in the V3.6 header
    /// (0..=140 without 50, and 142).
    pub fn is_known(c: i32) -> bool {
        ((0..=140).contains(&c) && c != 50) || c == 142
    }

    /// The header's name of the commands used here; `None` for the others.
    pub fn name(c: i32) -> Option<&'static str> {
        Some(match c {
            GET_SYSTEM_STATUS => "ES_C_GetSystemStatus",
            SET_UNITS => "ES_C_SetUnits",
            INITIALIZE => "ES_C_Initialize",
            SET_MEASUREMENT_MODE => "ES_C_SetMeasurementMode",
            SET_COORDINATE_SYSTEM_TYPE => "ES_C_SetCoordinateSystemType",
            SET_STATIONARY_MODE_PARAMS => "ES_C_SetStationaryModeParams",
            SET_CONTINUOUS_TIME_MODE_PARAMS => "ES_C_SetContinuousTimeModeParams",
            STOP_MEASUREMENT => "ES_C_StopMeasurement",
            START_MEASUREMENT => "ES_C_StartMeasurement",
            GO_LAST_MEASURED_POINT => "ES_C_GoLastMeasuredPoint",
            FIND_REFLECTOR => "ES_C_FindReflector",
            GO_POSITION => "ES_C_GoPosition",
            UNKNOWN => "ES_C_Unknown",
            GET_MEASUREMENT_STATUS_INFO => "ES_C_GetMeasurementStatusInfo",
            SET_STATISTIC_MODE => "ES_C_SetStatisticMode",
            _ => return None,
        })
    }

    /// The name, or `ES_Command <n>`.
    pub fn describe(c: i32) -> String {
        name(c).map_or_else(|| format!("ES_Command {c}"), str::to_string)
    }
}

/// `enum ES_StatisticMode`.
pub mod statistic_mode {
    /// `ES_SM_Standard`: a stationary measurement answers `SingleMeasResultT`.
    pub const STANDARD: i32 = 0;
    /// `ES_SM_Extended`: it answers `SingleMeasResult2T` (covariances too).
    pub const EXTENDED: i32 = 1;
}

/// `enum ES_ResultStatus`: the `status` of answers and results.
pub mod status {
    /// `ES_RS_AllOK`.
    pub const ALL_OK: i32 = 0;
    /// `ES_RS_ServerBusy`: "a pending command" (the header's comment).
    pub const SERVER_BUSY: i32 = 1;
    /// `ES_RS_NotImplemented`.
    pub const NOT_IMPLEMENTED: i32 = 2;
    /// `ES_RS_WrongParameter`.
    pub const WRONG_PARAMETER: i32 = 3;
    /// `ES_RS_WrongParameter1` (`WrongParameter2..7` follow at 5..=10).
    pub const WRONG_PARAMETER1: i32 = 4;
    /// `ES_RS_Parameter1OutOfRangeNOK`.
    pub const PARAMETER1_OUT_OF_RANGE_NOK: i32 = 12;
    /// `ES_RS_NoLastMeasuredPoint`.
    pub const NO_LAST_MEASURED_POINT: i32 = 28;
    /// `ES_RS_Unknown`.
    pub const UNKNOWN: i32 = 36;
    /// `ES_RS_TrackerNotInitialized`.
    pub const TRACKER_NOT_INITIALIZED: i32 = 39;
    /// `ES_RS_MeasurementStatusNotReady` (`ES_API_ERROR_OFFSET + 4`).
    pub const MEASUREMENT_STATUS_NOT_READY: i32 = 10_004;
    /// `ES_RS_NoStationaryResult` (`ES_API_ERROR_OFFSET + 9`).
    pub const NO_STATIONARY_RESULT: i32 = 10_009;
    /// `ES_RS_MultiConnectionsNotAllowed` (`ES_API_ERROR_OFFSET + 11`).
    pub const MULTI_CONNECTIONS_NOT_ALLOWED: i32 = 10_011;
    /// `ES_RS_SensorNotWarmedUp` (`ES_API_ERROR_OFFSET + 12`).
    pub const SENSOR_NOT_WARMED_UP: i32 = 10_012;
    /// `ES_RS_SensorNotStable` (`ES_API_ERROR_OFFSET + 13`).
    pub const SENSOR_NOT_STABLE: i32 = 10_013;
    /// `ES_RS_SystemNotReadyForMeasurement` (`ES_API_ERROR_OFFSET + 14`).
    pub const SYSTEM_NOT_READY_FOR_MEASUREMENT: i32 = 10_014;

    /// `ES_RS_...` names of values 0..=99, in order.
    const LOW: [&str; 100] = [
        "AllOK",
        "ServerBusy",
        "NotImplemented",
        "WrongParameter",
        "WrongParameter1",
        "WrongParameter2",
        "WrongParameter3",
        "WrongParameter4",
        "WrongParameter5",
        "WrongParameter6",
        "WrongParameter7",
        "Parameter1OutOfRangeOK",
        "Parameter1OutOfRangeNOK",
        "Parameter2OutOfRangeOK",
        "Parameter2OutOfRangeNOK",
        "Parameter3OutOfRangeOK",
        "Parameter3OutOfRangeNOK",
        "Parameter4OutOfRangeOK",
        "Parameter4OutOfRangeNOK",
        "Parameter5OutOfRangeOK",
        "Parameter5OutOfRangeNOK",
        "Parameter6OutOfRangeOK",
        "Parameter6OutOfRangeNOK",
        "WrongCurrentReflector",
        "NoCircleCenterFound",
        "NoSphereCenterFound",
        "NoTPFound",
        "NoWeathermonitorFound",
        "NoLastMeasuredPoint",
        "NoVideoCamera",
        "NoAdm",
        "NoNivel",
        "WrongTPFirmware",
        "DataBaseNotFound",
        "LicenseExpired",
        "UsageConflict",
        "Unknown",
        "NoDistanceSet",
        "NoTrackerConnected",
        "TrackerNotInitialized",
        "ModuleNotStarted",
        "ModuleTimedOut",
        "ErrorReadingModuleDb",
        "ErrorWritingModuleDb",
        "NotInCameraPosition",
        "TPHasServiceFirmware",
        "TPExternalControl",
        "WrongParameter8",
        "WrongParameter9",
        "WrongParameter10",
        "WrongParameter11",
        "WrongParameter12",
        "WrongParameter13",
        "WrongParameter14",
        "WrongParameter15",
        "WrongParameter16",
        "NoSuchCompensation",
        "MeteoDataOutOfRange",
        "InCompensationMode",
        "InternalProcessActive",
        "NoCopyProtectionDongleFound",
        "ModuleNotActivated",
        "ModuleWrongVersion",
        "DemoDongleExpired",
        "ParameterImportFromProbeFailed",
        "ParameterExportToProbeFailed",
        "TrkCompMeasCameraMismatch",
        "NoMeasurementCamera",
        "NoActiveMeasurementCamera",
        "NoMeasurementCamerasInDb",
        "NoCameraToTrackerCompSet",
        "NoCameraToTrackerCompInDb",
        "ProblemStoringCameraToTrackerFactorySet",
        "ProblemWithCameraInternalCalibration",
        "CommunicationWithMeasurementCameraFailed",
        "NoMeasurementProbe",
        "NoActiveMeasurementProbe",
        "NoMeasurementProbesInDb",
        "NoMeasurementProbeCompSet",
        "NoMeasurementProbeCompInDb",
        "ProblemStoringProbeFactorySet",
        "WrongActiveMeasurementProbeCompInDb",
        "CommunicationWithMeasurementProbeFailed",
        "NoMeasurementTip",
        "NoActiveMeasurementTip",
        "NoMeasurementTipsInDb",
        "NoMeasurementTipCompInDb",
        "NoMeasurementTipCompSet",
        "ProblemStoringTipAssembly",
        "ProblemReadingCompensationDb",
        "NoDataToImport",
        "ProblemSettingTriggerSource",
        "6DModeNotAllowed",
        "Bad6DResult",
        "NoTemperatureFromWM",
        "NoPressureFromWM",
        "NoHumidityFromWM",
        "6DMeasurementFace2NotAllowed",
        "InvalidInputData",
        "NoTriggerBoard",
    ];

    /// `ES_RS_...` names of values `ES_API_ERROR_OFFSET + 1..=21`, in order
    /// (`+ 5` is `AIFMStartUpBusy`, aliased `ADMStartUpBusy` from V3.6).
    const HIGH: [&str; 21] = [
        "NoMeasurementShankCompSet",
        "NoValidADMCompensation",
        "PressureSensorProblem",
        "MeasurementStatusNotReady",
        "AIFMStartUpBusy",
        "InvalidTipAdapter",
        "NoAtr",
        "NoOVC",
        "NoStationaryResult",
        "SensorNotLeveled",
        "MultiConnectionsNotAllowed",
        "SensorNotWarmedUp",
        "SensorNotStable",
        "SystemNotReadyForMeasurement",
        "CommunicationWithSensorFailed",
        "No_Sensor_Battery",
        "CompensatorNotAllowed",
        "WarmedUpStateReached",
        "NotLeveledForInitialization",
        "ADMHardwareProblem",
        "ATRHardwareProblem",
    ];

    /// The header's name of a result status without its `ES_RS_` prefix;
    /// `None` for a value the V3.6 header does not define.
    pub fn short_name(s: i32) -> Option<&'static str> {
        match s {
            0..=99 => Some(LOW[s as usize]),
            10_001..=10_021 => Some(HIGH[(s - 10_001) as usize]),
            _ => None,
        }
    }

    /// Whether the V3.6 header defines the result status `s`. A status it
    /// does not define is no answer of the tracker but a changed byte of
    /// the status field (emScon's packets carry no checksum): a garbled
    /// packet, not the instrument's fault. A defined status stays the
    /// instrument's word, even when a changed byte made it (`ES_RS_AllOK`
    /// with its low byte changed by 0x5a reads `ES_RS_ProblemReadingCompensationDb`).
    pub fn is_defined(s: i32) -> bool {
        short_name(s).is_some()
    }

    /// `ES_RS_<name>`, or `ES_ResultStatus <n>` for an undefined value.
    pub fn describe(s: i32) -> String {
        short_name(s).map_or_else(|| format!("ES_ResultStatus {s}"), |n| format!("ES_RS_{n}"))
    }
}

/// `enum ES_SystemStatusChange`: the events of `SystemStatusChangeT`.
pub mod status_change {
    /// `ES_SSC_LaserWarmedUp`.
    pub const LASER_WARMED_UP: i32 = 1;
    /// `ES_SSC_MeasStatus_NotReady`: the tracker cannot measure (no reflector
    /// locked: the beam is broken).
    pub const MEAS_STATUS_NOT_READY: i32 = 25;
    /// `ES_SSC_MeasStatus_Busy`.
    pub const MEAS_STATUS_BUSY: i32 = 26;
    /// `ES_SSC_MeasStatus_Ready`: a reflector is locked, measurements can be taken.
    pub const MEAS_STATUS_READY: i32 = 27;
    /// `ES_SSC_TPConnectionClosing`.
    pub const TP_CONNECTION_CLOSING: i32 = 997;
    /// `ES_SSC_ServerClosing`.
    pub const SERVER_CLOSING: i32 = 998;

    /// The header's name of an event without its `ES_SSC_` prefix (the two
    /// V3.6 events the header misspells `ES_SCC_` are named as spelled there).
    pub fn short_name(e: i32) -> Option<&'static str> {
        const LOW: [&str; 46] = [
            "DistanceSet",
            "LaserWarmedUp",
            "EnvironmentParamsChanged",
            "RefractionParamsChanged",
            "SearchParamsChanged",
            "AdmParamsChanged",
            "UnitsChanged",
            "ReflectorChanged",
            "SystemSettingsChanged",
            "TemperatureRangeChanged",
            "CameraParamsChanged",
            "CompensationChanged",
            "CoordinateSystemTypeChanged",
            "BoxRegionParamsChanged",
            "SphereRegionParamsChanged",
            "StationOrientationParamsChanged",
            "TransformationParamsChanged",
            "MeasurementModeChanged",
            "StationaryModeParamsChanged",
            "ContinuousTimeModeParamsChanged",
            "ContinuousDistanceModeParamsChanged",
            "GridModeParamsChanged",
            "CircleCenterModeParamsChanged",
            "SphereCenterModeParamsChanged",
            "StatisticModeChanged",
            "MeasStatus_NotReady",
            "MeasStatus_Busy",
            "MeasStatus_Ready",
            "MeasurementCountReached",
            "TriggerSourceChanged",
            "IsFace1",
            "IsFace2",
            "ExternalControlActive",
            "ServiceSoftwareActive",
            "MeasurementCameraChanged",
            "MeasurementCameraModeChanged",
            "ProbeChanged",
            "TipChanged",
            "TCamToTrackerCompensationChanged",
            "ProbeCompensationChanged",
            "TipToProbeCompensationChanged",
            "ExternTriggerParamsChanged",
            "TCamToTrackerCompensationDeleted",
            "MeasurementProbeCompensationDeleted",
            "MeasurementTipCompensationDeleted",
            "ManyMechanicalCompensationsInDB",
        ];
        Some(match e {
            0..=45 => LOW[e as usize],
            99 => "MeasStatus_6DStatusInvalid",
            100 => "MeasurementProbeButtonDown",
            101 => "MeasurementProbeButtonUp",
            102 => "ExternalTriggerEvent",
            103 => "ExternalTriggerStartEvent",
            104 => "ExternalTriggerStopEvent",
            105 => "ObjectTemperatureChanged",
            106 => "OverviewCameraChanged",
            107 => "NivelSensorChanged",
            110 => "ProbeButton1Down",
            111 => "ProbeButton1Up",
            112 => "ProbeButton1DoubleClick",
            120 => "ProbeButton2Down",
            121 => "ProbeButton2Up",
            122 => "ProbeButton2DoubleClick",
            130 => "ProbeButton3Down",
            131 => "ProbeButton3Up",
            132 => "ProbeButton3DoubleClick",
            140 => "ProbeButton4Down",
            141 => "ProbeButton4Up",
            142 => "ProbeButton4DoubleClick",
            143 => "QuickReleaseOpend",
            144 => "QuickReleaseClosed",
            145 => "LaserReachingLimit",
            146 => "LaserNotStabilized",
            150 => "MultipleTipAdapterConnected",
            151 => "InitializationStatusChanged",
            152 => "TiltSensorStatusChanged",
            800 => "CompensationModeStart",
            801 => "CompensationModeEnd",
            820 => "EmsysFilesImported",
            850 => "SensorDetected",
            851 => "SensorDisconnected",
            852 => "CompensatorStatusChanged",
            853 => "BatteryStatusChanged",
            996 => "CopyProtectionRemoved",
            997 => "TPConnectionClosing",
            998 => "ServerClosing",
            999 => "ServerStarted",
            _ => return None,
        })
    }

    /// `ES_SSC_<name>` (`ES_SCC_` for 151 and 152), or
    /// `ES_SystemStatusChange <n>` for an undefined value.
    pub fn describe(e: i32) -> String {
        let prefix = if matches!(e, 151 | 152) { "ES_SCC_" } else { "ES_SSC_" };
        short_name(e).map_or_else(|| format!("ES_SystemStatusChange {e}"), |n| format!("{prefix}{n}"))
    }
}

/// `enum ES_LengthUnit` (`Enum.h`).
pub mod length_unit {
    /// `ES_LU_Meter`.
    pub const METER: i32 = 0;
    /// `ES_LU_Millimeter`.
    pub const MILLIMETER: i32 = 1;
    /// `ES_LU_Micron`.
    pub const MICRON: i32 = 2;
    /// `ES_LU_Foot`.
    pub const FOOT: i32 = 3;
    /// `ES_LU_Yard`.
    pub const YARD: i32 = 4;
    /// `ES_LU_Inch`.
    pub const INCH: i32 = 5;
}

/// `enum ES_AngleUnit` (`Enum.h`).
pub mod angle_unit {
    /// `ES_AU_Radian`.
    pub const RADIAN: i32 = 0;
    /// `ES_AU_Degree`.
    pub const DEGREE: i32 = 1;
    /// `ES_AU_Gon`.
    pub const GON: i32 = 2;
}

/// `enum ES_TemperatureUnit` (`Enum.h`).
pub mod temperature_unit {
    /// `ES_TU_Celsius`.
    pub const CELSIUS: i32 = 0;
    /// `ES_TU_Fahrenheit`.
    pub const FAHRENHEIT: i32 = 1;
}

/// `enum ES_PressureUnit` (`Enum.h`).
pub mod pressure_unit {
    /// `ES_PU_Mbar`.
    pub const MBAR: i32 = 0;
    /// `ES_PU_HPascal`.
    pub const HPASCAL: i32 = 1;
    /// `ES_PU_KPascal`.
    pub const KPASCAL: i32 = 2;
    /// `ES_PU_MmHg`.
    pub const MMHG: i32 = 3;
    /// `ES_PU_Psi`.
    pub const PSI: i32 = 4;
    /// `ES_PU_InH2O`.
    pub const INH2O: i32 = 5;
    /// `ES_PU_InHg`.
    pub const INHG: i32 = 6;
}

/// `enum ES_HumidityUnit` (`Enum.h`).
pub mod humidity_unit {
    /// `ES_HU_RH`.
    pub const RH: i32 = 0;
}

/// `enum ES_CoordinateSystemType` (`Enum.h`): `ES_CS_RHR` (0, right-handed
/// Cartesian) to `ES_CS_SCC` (7).
pub mod coordinate_system {
    /// `ES_CS_RHR`: right-handed rectangular.
    pub const RHR: i32 = 0;
    /// `ES_CS_SCC`: the last value.
    pub const SCC: i32 = 7;
}

/// `enum ES_MeasMode`: `ES_MM_Stationary` (0) to `ES_MM_6DCircleCenter` (11).
pub mod meas_mode {
    /// `ES_MM_Stationary`.
    pub const STATIONARY: i32 = 0;
    /// `ES_MM_ContinuousTime`: a point every `lTimeSeparation`.
    pub const CONTINUOUS_TIME: i32 = 1;
    /// `ES_MM_6DCircleCenter`: the last value.
    pub const LAST: i32 = 11;
}

/// `enum ES_MeasurementStatus`: each point of a continuous measurement.
pub mod measurement_status {
    /// `ES_MS_AllOK`.
    pub const ALL_OK: i32 = 0;
    /// `ES_MS_TriggerTimeViolation`: the last value.
    pub const LAST: i32 = 4;
}

/// `enum ES_RegionType`.
pub mod region_type {
    /// `ES_RT_Sphere`.
    pub const SPHERE: i32 = 0;
}

/// `enum ES_TrackerProcessorStatus`.
pub mod tracker_processor_status {
    /// `ES_TPS_CompensationSet`: booted and compensated, not initialised.
    pub const COMPENSATION_SET: i32 = 4;
    /// `ES_TPS_Initialized`.
    pub const INITIALIZED: i32 = 5;
}

/// `enum ES_LaserProcessorStatus`.
pub mod laser_status {
    /// `ES_LPS_LaserHeatingUp`.
    pub const LASER_HEATING_UP: i32 = 2;
    /// `ES_LPS_LaserReady`.
    pub const LASER_READY: i32 = 3;
}

/// `enum ES_ADMStatus`.
pub mod adm_status {
    /// `ES_AS_ADMReady`.
    pub const ADM_READY: i32 = 2;
}

/// `enum ES_WeatherMonitorStatus`.
pub mod weather_monitor_status {
    /// `ES_WMS_ReadOnly`.
    pub const READ_ONLY: i32 = 1;
}

/// `enum ES_MeasurementStatusInfo`: bits of `lMeasurementStatusInfo`.
pub mod measurement_status_info {
    /// `ES_MSI_TrackerFound`.
    pub const TRACKER_FOUND: i32 = 1;
    /// `ES_MSI_TrackerCompensationFound`.
    pub const TRACKER_COMPENSATION_FOUND: i32 = 2;
    /// `ES_MSI_ADMFound`.
    pub const ADM_FOUND: i32 = 4;
    /// `ES_MSI_ADMCompensationFound`.
    pub const ADM_COMPENSATION_FOUND: i32 = 8;
    /// `ES_MSI_ReflectorFound`: a reflector is locked on.
    pub const REFLECTOR_FOUND: i32 = 2048;
    /// `ES_MSI_InFace1`.
    pub const IN_FACE1: i32 = 4096;
    /// `ES_MSI_NivelInWorkingRange`.
    pub const NIVEL_IN_WORKING_RANGE: i32 = 32768;
    /// `ES_MSI_Initialized`.
    pub const INITIALIZED: i32 = 65536;
}
