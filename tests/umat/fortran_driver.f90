! Calls the UMAT once as Abaqus would (a Fortran caller: arguments by reference, CMNAME's hidden
! length): a 3D elastic unloading increment of the frictional model from a K0 state, then the
! same call with a bad PROPS(5), whose message must name the material and the property.
program umat_fortran_driver
  use, intrinsic :: iso_c_binding
  implicit none
  interface
    function granflow_umat_last_error() bind(c, name="granflow_umat_last_error")
      import :: c_ptr
      type(c_ptr) :: granflow_umat_last_error
    end function
  end interface
  integer, parameter :: ntens = 6, nstatv = 13, nprops = 14
  double precision :: stress(ntens), statev(nstatv), ddsdde(ntens, ntens), sse, spd, scd, rpl
  double precision :: ddsddt(ntens), drplde(ntens), drpldt, stran(ntens), dstran(ntens), time(2), dtime
  double precision :: temp, dtemp, predef(1), dpred(1), props(nprops), coords(3), drot(3, 3), pnewdt
  double precision :: celent, dfgrd0(3, 3), dfgrd1(3, 3)
  integer :: noel, npt, layer, kspt, jstep(4), kinc, i
  character(len=80) :: cmname
  character(len=:), allocatable :: msg

  ! Table 1 set (data/params/frictional_element.toml), e0 = 0.80
  props = [1d0, 150d0, 0.22d0, 0.6d0, 30d0, 0.937d0, 0.022d0, 0.71d0, 4d0, 1d-3, 1d0, 1d0, 101.3d3, 0.80d0]
  cmname = 'SAND-1'
  stress = [-100d3, -200d3, -100d3, 0d0, 0d0, 0d0]  ! on the yield surface (eps_pd set by the UMAT)
  statev = 0
  stran = 0
  dstran = [0d0, 1d-5, 0d0, 0d0, 0d0, 0d0]  ! axial unloading: elastic
  drot = 0
  do i = 1, 3
    drot(i, i) = 1
  end do
  dfgrd0 = drot
  dfgrd1 = drot
  time = 0
  dtime = 1
  pnewdt = 1
  noel = 7
  npt = 3
  call umat(stress, statev, ddsdde, sse, spd, scd, rpl, ddsddt, drplde, drpldt, stran, dstran, time, dtime, &
            temp, dtemp, predef, dpred, cmname, 3, 3, ntens, nstatv, props, nprops, coords, drot, pnewdt, &
            celent, dfgrd0, dfgrd1, noel, npt, layer, kspt, jstep, kinc)
  print '(a, 6es12.4)', 'stress', stress
  print '(a, 4es12.4)', 'statev(1:4)', statev(1:4)
  print '(a, 3es12.4, a, f6.3)', 'ddsdde(2,2), (1,2), (4,4)', ddsdde(2, 2), ddsdde(1, 2), ddsdde(4, 4), &
    '  pnewdt', pnewdt
  ! elastic unloading (tension +): every normal stress rises, the lateral ones alike;
  ! e = (1 + e0) exp(1e-5) - 1; isotropic elasticity: C11 - C12 = 2 G = 2 C44 (engineering shear)
  if (pnewdt /= 1d0) error stop 'pnewdt changed on a good call'
  if (.not. (stress(2) > -200d3 .and. stress(1) > -100d3 .and. stress(1) == stress(3))) error stop 'stress'
  if (abs(statev(1) - (1.80d0 * exp(1d-5) - 1d0)) > 1d-12) error stop 'void ratio'
  if (.not. (ddsdde(1, 2) > 0 .and. abs(ddsdde(2, 2) - ddsdde(1, 2) - 2 * ddsdde(4, 4)) < 1d-2 * ddsdde(4, 4))) &
    error stop 'tangent'

  props(5) = 95d0  ! phi_c_deg out of (0, 90)
  statev = 0
  call umat(stress, statev, ddsdde, sse, spd, scd, rpl, ddsddt, drplde, drpldt, stran, dstran, time, dtime, &
            temp, dtemp, predef, dpred, cmname, 3, 3, ntens, nstatv, props, nprops, coords, drot, pnewdt, &
            celent, dfgrd0, dfgrd1, noel, npt, layer, kspt, jstep, kinc)
  msg = c_string(granflow_umat_last_error())
  print '(a)', 'bad PROPS(5): ' // msg
  if (.not. (pnewdt < 1d0)) error stop 'pnewdt not reduced on bad PROPS'
  if (index(msg, 'material SAND-1, element 7, point 3') == 0) error stop 'CMNAME/NOEL/NPT not in the message'
  if (index(msg, 'PROPS(5)') == 0 .or. index(msg, 'phi_c_deg') == 0) error stop 'PROPS(5) not named'
  deallocate(msg)  ! main-program variables are never freed: LeakSanitizer would report it
  print '(a)', 'OK'

contains

  function c_string(p) result(s)
    type(c_ptr), intent(in) :: p
    character(len=:), allocatable :: s
    character(kind=c_char), pointer :: c(:)
    integer :: n
    call c_f_pointer(p, c, [4096])
    n = 0
    do while (c(n + 1) /= c_null_char)
      n = n + 1
    end do
    allocate(character(len=n) :: s)
    do n = 1, len(s)
      s(n:n) = c(n)
    end do
  end function

end program
