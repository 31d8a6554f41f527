"""Weather files: ERA5, GFS, WAVEWATCH III and CMEMS (NetCDF, GRIB) decoded by xarray into gridded fields."""
